"""Guess how a delimited text file is written (separator, decimal mark, encoding, lines above
the header, comment prefix, units row), to say what to write under ``csv:`` when reading it
with the options given fails."""

from __future__ import annotations

import codecs
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from spa.datasets.options import WHITESPACE

_HEAD = 1 << 16  # bytes looked at
_SEPS = ("\t", ";", "|", ",", WHITESPACE)  # tried in this order
_COMMENTS = ("#", "%", "//", "!")
_NUMBER = re.compile(r"[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?|nan|NaN|-?inf|")
_UNIT = re.compile(
    r"[\[(]?(s|ms|us|µs|min|h|bar|mbar|kPa|MPa|Pa|hPa|psi|V|mV|A|mA|%|-|°C|K|Hz|1|)[\])]?"
)
_DATA_LINES = 40  # last lines of the head that decide the separator


def _encoding(head: bytes) -> tuple[str, str]:
    """The codec and the text of ``head`` (its last, maybe cut, line dropped)."""
    for bom, codec in (
        (codecs.BOM_UTF32_LE, "utf-32"),
        (codecs.BOM_UTF32_BE, "utf-32"),
        (codecs.BOM_UTF8, "utf-8"),
        (codecs.BOM_UTF16_LE, "utf-16"),
        (codecs.BOM_UTF16_BE, "utf-16"),
    ):
        if head.startswith(bom):
            return codec, head.decode(codec if codec != "utf-8" else "utf-8-sig", "replace")
    if b"\x00" in head:
        even, odd = head[0::2].count(0), head[1::2].count(0)
        codec = "utf-16-le" if odd > even else "utf-16-be"
        return codec, head[: len(head) // 2 * 2].decode(codec, "replace")
    for codec in ("utf-8", "cp1252"):
        try:
            return codec, head.decode(codec)
        except UnicodeDecodeError as exc:
            if codec == "utf-8" and exc.start >= len(head) - 4:  # a character cut at the end
                return codec, head[: exc.start].decode(codec)
    return "latin-1", head.decode("latin-1")


def _fields(line: str, sep: str) -> list[str]:
    return line.split() if sep == WHITESPACE else [f.strip() for f in line.split(sep)]


def _units(fields: list[str]) -> bool:
    """True when every field names a unit (or is empty), as in a units row."""
    names = [f.strip().strip('"') for f in fields]
    return any(names) and all(_UNIT.fullmatch(f) for f in names)


def _data_like(fields: list[str], width: int) -> bool:
    """True for a row of data: ``width`` fields, at least half of the filled ones numbers."""
    filled = [f.strip().strip('"') for f in fields if f.strip()]
    numbers = sum(bool(_NUMBER.fullmatch(f)) for f in filled)
    return len(fields) == width and numbers > 0 and 2 * numbers >= len(filled)


def _sniff(path: Path) -> dict[str, Any]:
    """Everything :func:`sniff_delimited` finds, plus the header's line and the units row."""
    with path.open("rb") as fh:
        head = fh.read(_HEAD)
    full = len(head) < _HEAD
    encoding, text = _encoding(head)
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if not full and len(lines) > 1:
        lines.pop()  # cut by the end of the head
    while lines and not lines[-1].strip():
        lines.pop()
    starts = [c for c in _COMMENTS if any(x.lstrip().startswith(c) for x in lines)]
    comment = starts[0] if starts else None
    body = [(i, x) for i, x in enumerate(lines) if not (comment and x.lstrip().startswith(comment))]
    tail = [x for _, x in body[-max(1, min(_DATA_LINES, len(body) // 2)) :]]
    sep, width = ",", 1
    for candidate in _SEPS:
        counts = {len(_fields(x, candidate)) for x in tail}
        if len(counts) == 1 and (n := counts.pop()) >= 2:
            sep, width = candidate, n
            break
    decimal = "."
    if sep != ",":
        cells = [f for x in tail for f in _fields(x, sep)]
        if any(re.fullmatch(r"[+-]?\d*,\d+([eE][+-]?\d+)?", f) for f in cells) and not any(
            re.fullmatch(r"[+-]?\d*\.\d+([eE][+-]?\d+)?", f) for f in cells
        ):
            decimal = ","
    # the data: the trailing lines of numbers; the header: the line above them
    first = len(body)
    while first > 0 and _data_like(_fields(body[first - 1][1], sep), width):
        first -= 1
    header = first - 1
    units_row = header >= 1 and _units(_fields(body[header][1], sep))
    if units_row and len(_fields(body[header - 1][1], sep)) == width:
        header -= 1
    else:
        units_row = False
    header_index = body[header][0] if header >= 0 else 0
    preamble = lines[:header_index]
    skip = 0 if comment and all(x.lstrip().startswith(comment) for x in preamble) else header_index
    return {
        "sep": sep,
        "decimal": decimal,
        "encoding": encoding,
        "skip_rows": skip,
        "comment": comment,
        "units_row": units_row,
        "header_line": header_index + 1,
        "units": _fields(body[header + 1][1], sep) if units_row else [],
    }


def sniff_delimited(path: str | Path) -> dict[str, Any]:
    """Guess the ``csv:`` options of a delimited text file from its first 64 KiB.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    dict
        ``sep`` (``","``, ``";"``, ``"\\t"``, ``"|"`` or ``"whitespace"``), ``decimal``
        (``"."`` or ``","``), ``encoding`` (``"utf-8"``, ``"utf-16"`` with a byte-order mark,
        ``"utf-16-le"``/``"utf-16-be"`` without, ``"cp1252"`` or ``"latin-1"``),
        ``skip_rows`` (lines above the header that are not comments), ``comment`` (a prefix
        such as ``"#"``, or None) and ``units_row`` (the line under the header holds units).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "run.csv"
    >>> _ = f.write_bytes("Zeit;Druck\\ns;bar\\n0,0;1,5\\n0,1;1,6\\n".encode("cp1252"))
    >>> sniff_delimited(f)
    {'sep': ';', 'decimal': ',', 'encoding': 'utf-8', 'skip_rows': 0, 'comment': None, \
'units_row': True}
    """
    found = _sniff(Path(path))
    return {
        k: found[k] for k in ("sep", "decimal", "encoding", "skip_rows", "comment", "units_row")
    }


def _flow(options: Mapping[str, Any]) -> str:
    """``options`` as a YAML flow mapping, e.g. ``{sep: ';', decimal: ','}``."""

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str) and (v == WHITESPACE or re.fullmatch(r"[A-Za-z0-9_-]+", v)):
            return v
        return "'\\t'" if v == "\t" else repr(v) if isinstance(v, str) else str(v)

    return "{" + ", ".join(f"{k}: {value(v)}" for k, v in options.items()) + "}"


def _name(codec: str | None) -> str:
    return "UTF-8" if codec is None or codecs.lookup(codec).name == "utf-8" else codec


#: A time of day and an arrow before every line: the Arduino IDE's serial monitor with
#: "Show timestamp" on (``12:00:01.123 -> 0.52``).
_SERIAL_PREFIX = re.compile(r"\s*\d{1,2}:\d{2}:\d{2}([.,]\d+)?\s*->\s?")


def prefix_hint(path: Path) -> str:
    """What to do when every line of a text file (but a header) starts with a serial
    monitor's time stamp (``12:00:01.123 -> ``), which no ``csv:`` option reads; ``""``
    otherwise.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "log.txt"
    >>> _ = f.write_text("12:00:01.123 -> 0.52\\n12:00:01.143 -> 0.61\\n")
    >>> prefix_hint(f)[:60]
    '; every line starts with a time of day and an arrow, `12:00:'
    """
    try:
        with path.open("rb") as fh:
            head = fh.read(_HEAD)
    except OSError:
        return ""
    lines = _encoding(head)[1].splitlines()
    if len(head) >= _HEAD and len(lines) > 1:
        lines.pop()  # cut by the end of the head
    lines = [x for x in lines if x.strip()]
    body = lines[1:] if len(lines) > 1 else lines  # the first line may be a header
    if not body or not all(_SERIAL_PREFIX.match(x) for x in body):
        return ""
    first = next(x for x in lines if _SERIAL_PREFIX.match(x))
    example = _SERIAL_PREFIX.match(first).group(0).strip()  # type: ignore[union-attr]
    return (
        f"; every line starts with a time of day and an arrow, `{example} ` (a serial "
        "monitor's time stamps, \"Show timestamp\" in the Arduino IDE), which spa does not "
        "read: log without them, or strip them into a copy, e.g. "
        "`sed -E 's/^ *[0-9:.,]+ *-> ?//' in.txt > out.txt` (keep the original), then "
        "declare the step with sample_step"
    )


def csv_hint(path: Path, options: Mapping[str, Any]) -> str:
    """What the file looks like where it differs from ``options`` (the resolved ``csv:``
    options it was read with), and what to write; ``""`` when nothing differs."""
    prefix = prefix_hint(path)
    if prefix:  # no csv: option reads it: the other guesses would mislead
        return prefix
    try:
        found = _sniff(path)
    except Exception:  # a hint is a courtesy: never let it hide the problem it explains
        return ""
    said = []
    change: dict[str, Any] = {}
    given = _name(options.get("encoding"))
    if found["encoding"] not in ("utf-8", "utf-16", "utf-32") and _name(found["encoding"]) != given:
        if not (given != "UTF-8" and found["encoding"] in ("cp1252", "latin-1")):
            change["encoding"] = found["encoding"]
            said.append(
                f"is not {given} (the bytes fit {found['encoding']}): "
                f"`csv: {_flow({'encoding': found['encoding']})}`"
            )
    layout = {k: found[k] for k in ("sep", "decimal") if found[k] != options.get(k)}
    if layout:
        change.update(layout)
        sep = "whitespace" if found["sep"] == WHITESPACE else repr(found["sep"]).replace("'", "`")
        said.append(
            f"looks {sep}-separated with `{found['decimal']}` as decimal mark: "
            f"`csv: {_flow({'sep': found['sep'], 'decimal': found['decimal']})}`"
        )
    if found["skip_rows"] != options.get("skip_rows", 0):
        change["skip_rows"] = found["skip_rows"]
        said.append(
            f"has its header on line {found['header_line']}: "
            f"`csv: {_flow({'skip_rows': found['skip_rows']})}`"
        )
    if found["comment"] and found["comment"] != options.get("comment"):
        change["comment"] = found["comment"]
        said.append(
            f"has lines starting with {found['comment']!r}: "
            f"`csv: {_flow({'comment': found['comment']})}`"
        )
    if found["units_row"] and not options.get("units_row"):
        change["units_row"] = True
        units = ", ".join(u for u in found["units"] if u)
        said.append(
            f"has units on line {found['header_line'] + 1} ({units}): `csv: {{units_row: true}}`"
        )
    if not said:
        return ""
    return (
        "; judging by its content, the file "
        + "; it ".join(said)
        + f"; add `csv: {_flow(change)}` to the run or the dataset"
    )
