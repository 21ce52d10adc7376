"""Options of ``dataset.yaml`` that a run may override key by key: ``columns:``, ``units:``
and ``csv:`` (how delimited text is read).

Each checker is pure: it takes the value written in ``dataset.yaml``, the map it overrides
and the key it sits under (``units`` or ``runs[2].units``), and returns the merged map and
the problems found as ``(key, message)`` pairs.
"""

from __future__ import annotations

import codecs
from collections.abc import Mapping
from typing import Any

from spa.datasets.contract import (
    _QUANTITY,
    _UNIT_KEYS,
    CANONICAL_COLUMNS,
    PRESSURE_UNITS,
    TIME_UNITS,
)
from spa.datasets.problems import _is_one_of, _one_of, _suggest, _unknown_key

#: Keys of ``csv:``, and the values each takes.
CSV_KEYS: Mapping[str, str] = {
    "sep": "one character, '\\t' or whitespace",
    "decimal": "'.' or ','",
    "encoding": "a Python codec name such as utf-8, cp1252, latin-1, utf-16",
    "skip_rows": "an integer >= 0 (lines above the header)",
    "comment": "a non-empty prefix such as '#'",
    "units_row": "true or false",
    "header": "true or false (absent: a first line of numbers only is data, and the columns "
    "are named by position, col1, col2, ...)",
}

#: Other names of ``csv:`` keys, accepted as the key they stand for.
CSV_ALIASES: Mapping[str, str] = {"delimiter": "sep"}

#: The name of the column at (1-based) position ``i`` of a file without a header line.
POSITIONAL = "col{}"

#: The options of delimited text when ``csv:`` says nothing (``encoding: None`` is UTF-8,
#: with or without a byte-order mark, or UTF-16 with one).
CSV_DEFAULTS: Mapping[str, Any] = {
    "sep": ",",
    "decimal": ".",
    "encoding": None,
    "skip_rows": 0,
    "comment": None,
    "units_row": False,
}

#: Defaults that differ by file ending.
CSV_SUFFIX_DEFAULTS: Mapping[str, Mapping[str, Any]] = {".tsv": {"sep": "\t"}}

#: The ``sep`` standing for runs of spaces and tabs.
WHITESPACE = "whitespace"

Found = list[tuple[str, str]]


def _check_sep(value: Any) -> str | None:
    if value == WHITESPACE or (isinstance(value, str) and len(value) == 1):
        if value in ("\n", "\r", '"'):
            return f"sep {value!r} cannot separate fields; expected {CSV_KEYS['sep']}"
        return None
    return f"sep {value!r} is not {CSV_KEYS['sep']}{_suggest(value, [WHITESPACE])}"


def _check_csv_value(key: str, value: Any) -> str | None:
    """The problem with ``csv.<key>: value``, or None."""
    if key == "sep":
        return _check_sep(value)
    if key == "decimal":
        return None if value in (".", ",") else f"decimal {value!r} is not {CSV_KEYS[key]}"
    if key == "encoding":
        if not isinstance(value, str):
            return f"encoding {value!r} is not {CSV_KEYS[key]}"
        try:
            codecs.lookup(value)
        except LookupError:
            return f"unknown encoding {value!r}; expected {CSV_KEYS[key]}"
        return None
    if key == "skip_rows":
        ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
        return None if ok else f"skip_rows {value!r} is not {CSV_KEYS[key]}"
    if key == "comment":
        ok = isinstance(value, str) and value.strip() and "\n" not in value
        return None if ok else f"comment {value!r} is not {CSV_KEYS[key]}"
    return None if isinstance(value, bool) else f"{key} {value!r} is not {CSV_KEYS[key]}"


def check_csv(value: Any, base: Mapping[str, Any], where: str) -> tuple[dict[str, Any], Found]:
    """Check a ``csv:`` mapping and merge it over ``base``.

    Parameters
    ----------
    value : object
        The value of ``csv:`` in ``dataset.yaml`` (None when absent).
    base : mapping
        Options it overrides, key by key (the dataset's, for a run).
    where : str
        Key it sits under, ``csv`` or ``runs[i].csv``, used to name problems.

    Returns
    -------
    options : dict
        ``base`` updated with the valid keys of ``value``.
    problems : list of (str, str)
        ``(key, message)`` for each unknown key or bad value.

    Examples
    --------
    >>> check_csv({"sep": ";", "decimal": ","}, {}, "csv")
    ({'sep': ';', 'decimal': ','}, [])
    >>> check_csv({"sep": "::"}, {}, "csv")[1][0][0]
    'csv.sep'
    >>> check_csv({"delimiter": ";"}, {}, "csv")  # another name for sep
    ({'sep': ';'}, [])
    """
    merged = dict(base)
    if value is None:
        return merged, []
    if not isinstance(value, Mapping):
        example = "{sep: ';', decimal: ','}"
        return merged, [(where, f"csv must be a mapping such as {example}, got {value!r}")]
    found: Found = []
    for alias, key in CSV_ALIASES.items():
        if alias in value and key in value and value[alias] != value[key]:
            found.append(
                (
                    f"{where}.{alias}",
                    f"{alias} {value[alias]!r} and {key} {value[key]!r} are given and differ; "
                    f"{alias} is another name for {key}: give one",
                )
            )
    for given, item in value.items():
        key = CSV_ALIASES.get(given, given) if isinstance(given, str) else given
        if key not in CSV_KEYS:
            found.append((f"{where}.{given}", _unknown_key(given, [*CSV_KEYS, *CSV_ALIASES])))
            continue
        message = _check_csv_value(str(key), item)
        if message:
            found.append((f"{where}.{given}", message))
        else:
            merged[str(key)] = item
    if not found and merged.get("decimal") == "," and merged.get("sep", ",") == ",":
        found.append((f"{where}.decimal", "decimal ',' needs a sep other than ',', e.g. sep: ';'"))
    if not found and merged.get("header") is False and merged.get("units_row"):
        found.append(
            (
                f"{where}.units_row",
                "units_row: true needs a header line above it, but header: false says the "
                "file has none",
            )
        )
    return merged, found


def csv_options(options: Mapping[str, Any], suffix: str) -> dict[str, Any]:
    """Every option of delimited text for a file ending in ``suffix``: the defaults, the
    defaults of that ending (``.tsv``: tab), then ``options``.

    Examples
    --------
    >>> csv_options({"decimal": ","}, ".tsv")["sep"]
    '\\t'
    """
    return {**CSV_DEFAULTS, **CSV_SUFFIX_DEFAULTS.get(suffix.lower(), {}), **options}


def check_units(value: Any, base: Mapping[str, str], where: str) -> tuple[dict[str, str], Found]:
    """Check a ``units:`` mapping (keys ``time``, ``pressure``) and merge it over ``base``.

    ``where`` is ``units`` or ``runs[i].units``; returns the merged units and the problems as
    for :func:`check_csv`.
    """
    merged = dict(base)
    if value is None:
        return merged, []
    if not isinstance(value, Mapping):
        return merged, [
            (where, f"units must be a mapping like {{time: ms, pressure: kPa}}, got {value!r}")
        ]
    found: Found = [
        (f"{where}.{k}", _unknown_key(k, _UNIT_KEYS)) for k in value if k not in _UNIT_KEYS
    ]
    for key, table in (("time", TIME_UNITS), ("pressure", PRESSURE_UNITS)):
        if key not in value:
            continue
        unit = value[key]
        if not _is_one_of(unit, table):
            found.append(
                (
                    f"{where}.{key}",
                    f"{key} unit {unit!r} is not one of {_one_of(table)}{_suggest(unit, table)}",
                )
            )
        else:
            merged[key] = unit
    return merged, found


#: Canonical columns a ``columns:`` mapping may leave out with ``null`` (``t`` and ``p`` are
#: read for every run).
OPTIONAL_COLUMNS: tuple[str, ...] = tuple(c for c in CANONICAL_COLUMNS if c not in ("t", "p"))

#: Columns ``null`` may leave out: the optional ones, and ``t`` for a log without time stamps
#: (its ``sample_step`` then gives the time: :mod:`spa.datasets.clock`).
NULLABLE_COLUMNS: tuple[str, ...] = ("t", *OPTIONAL_COLUMNS)


def check_columns(
    value: Any, base: Mapping[str, str | None], where: str
) -> tuple[dict[str, str | None], Found]:
    """Check a ``columns:`` mapping (canonical name to the name in the files) and merge it
    over ``base``; then check no file column serves two canonical ones.

    ``where`` is ``columns`` or ``runs[i].columns``; returns as for :func:`check_csv`.

    Notes
    -----
    ``null`` for an optional canonical column (``valve``, ``u``, ``r``) leaves it out: the
    files have no such column (merged value None); so does ``t: null`` for a log without
    time stamps, which then needs ``sample_step`` (checked by :mod:`spa.datasets.spec`). A
    canonical name standing for itself (not mapped, or mapped to its own name by ``base``)
    gives way to a name of this mapping
    that claims the same file column: ``{valve: u}`` on a ``time,u,pressure`` log, whose
    only command column is the 0/1 valve, leaves ``u`` out. Two names of one mapping (or of
    ``base``) given the same file column are a problem.

    Examples
    --------
    >>> base = {c: c for c in CANONICAL_COLUMNS}
    >>> check_columns({"valve": "u"}, base, "columns")[0]["u"] is None
    True
    >>> check_columns({"valve": "x", "u": "x"}, base, "columns")[1][0][1][:31]
    "file column 'x' is used for sev"
    """
    merged: dict[str, str | None] = dict(base)
    if value is None:
        return merged, []
    if not isinstance(value, Mapping):
        return merged, [
            (
                where,
                f"columns must map canonical names ({_one_of(CANONICAL_COLUMNS)}) to the names "
                f"in the files, e.g. {{t: time_ms, p: P_kPa}}; got {value!r}",
            )
        ]
    found: Found = []
    given: set[str] = set()
    for key, name in value.items():
        if key not in CANONICAL_COLUMNS:
            found.append(
                (
                    f"{where}.{key}",
                    f"unknown canonical column {key!r}{_suggest(key, CANONICAL_COLUMNS)}; "
                    f"allowed: {_one_of(CANONICAL_COLUMNS)}",
                )
            )
        elif name is None and key in NULLABLE_COLUMNS:
            merged[key] = None
        elif name is None:
            found.append(
                (
                    f"{where}.{key}",
                    f"{key!r} cannot be left out (null): every run needs its "
                    f"{_QUANTITY[key]}; name its column",
                )
            )
        elif not isinstance(name, str) or not name:
            found.append(
                (
                    f"{where}.{key}",
                    f"column name for {key!r} must be a non-empty string, got {name!r}",
                )
            )
        else:
            merged[key] = name
            given.add(key)
    for dup in sorted({n for n in merged.values() if n is not None}):
        which = [c for c, n in merged.items() if n == dup]
        if len(which) < 2:
            continue
        # a name standing for itself gives way to one this mapping gives the same column
        yielding = [c for c in which if c == dup and c not in given and c in OPTIONAL_COLUMNS]
        if yielding and len(which) - len(yielding) == 1:
            merged[yielding[0]] = None
            continue
        optional = [c for c in which if c in OPTIONAL_COLUMNS]
        leave = f"; or leave one out, e.g. {{{optional[-1]}: null}}" if optional else ""
        found.append(
            (
                where,
                f"file column {dup!r} is used for several canonical columns {which} (a "
                f"canonical name not mapped under columns: stands for itself{leave})",
            )
        )
    return merged, found
