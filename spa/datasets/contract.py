"""The dataset contract's vocabulary: file names, run kinds, canonical columns, units and
limits (see ``raw/README.md``)."""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa

#: Name of the description file inside a dataset folder.
SPEC_FILE = "dataset.yaml"

#: The file that makes a dataset folder a planned session's (``spa plan``).
PLAN_FILE = "plan.yaml"

#: What ``spa plan`` and ``spa record`` write into a session's folder beside the runs: the
#: plan, the checklist, the comparison a verification session gets, and the board's player
#: (a folder). Validation and ingest pass over them in a folder that holds :data:`PLAN_FILE`.
PLAN_WRITTEN: tuple[str, ...] = (PLAN_FILE, "checklist.md", "verification.csv", "player/")


#: Kinds of run.
KINDS: tuple[str, ...] = (
    "charge",
    "discharge",
    "pulse",
    "staircase",
    "sine",
    "chirp",
    "closed_loop",
)


#: Kinds of run driven through a pulse modulator: they need ``modulator`` (and the open-loop
#: ones ``u``; a ``closed_loop`` run, under PI control, needs the set-point ``r`` and its
#: ``controller``).
MODULATED_KINDS: tuple[str, ...] = ("staircase", "sine", "chirp", "closed_loop")


#: Where the data come from.
ORIGINS: tuple[str, ...] = ("bench", "synthetic")


#: Canonical column names, in the order of a run table.
CANONICAL_COLUMNS: tuple[str, ...] = ("t", "p", "valve", "u", "r")


#: Columns each kind of run must have.
REQUIRED_COLUMNS: Mapping[str, tuple[str, ...]] = {
    "charge": ("t", "p"),
    "discharge": ("t", "p"),
    "pulse": ("t", "p", "valve"),
    "staircase": ("t", "p", "u"),
    "sine": ("t", "p", "u"),
    "chirp": ("t", "p", "u"),
    "closed_loop": ("t", "p", "r"),
}


#: Columns whose absence is a warning, not an error.
RECOMMENDED_COLUMNS: Mapping[str, tuple[str, ...]] = {k: ("valve",) for k in MODULATED_KINDS}


#: Seconds per unit of time.
TIME_UNITS: Mapping[str, float] = {"s": 1.0, "ms": 1e-3}


#: Bar per unit of (gauge) pressure.
PRESSURE_UNITS: Mapping[str, float] = {"bar": 1.0, "mbar": 1e-3, "kPa": 1e-2, "psi": 0.0689475729}


#: Plausible range of gauge pressure for a soft actuator, in bar: a little below full vacuum
#: (-1.013 bar, with room for sensor offset) up to well above any supply used with one.
P_MIN_BAR = -1.1


P_MAX_BAR = 20.0

#: Plausible supply pressure of a soft actuator's bench, bar gauge (config
#: ``datasets.plausible_supply_bar``): outside it, a unit is likely declared wrong.
PLAUSIBLE_SUPPLY_BAR = (0.05, 20.0)

#: The supply pressures soft actuators are run at, bar gauge (the product's stated range of
#: ``k2``): inside the plausible range, a reading of the supply in another unit much nearer
#: its middle (by ratio) is taken for the unit meant (:func:`spa.datasets.checks.likelier_unit`).
TYPICAL_SUPPLY_BAR = (0.2, 6.0)


#: Parquet key-value metadata key holding the run's description as JSON.
META_KEY = b"spa"


#: Value of ``meta["format"]`` in every run table.
RUN_TABLE_FORMAT = "spa.run/1"


# Units whose factor is the inverse of an integer: divide by it, which rounds correctly.
_DIVISORS = {"ms": 1000.0, "mbar": 1000.0, "kPa": 100.0}


# File ending -> format, whose reader is ``spa.datasets.readers.READERS[format]``; delimited
# text is "csv".
_FORMATS = {
    ".csv": "csv",
    ".parquet": "parquet",
    ".mat": "mat",
    ".txt": "csv",
    ".tsv": "csv",
    ".dat": "csv",
    ".log": "csv",
    ".lvm": "lvm",
    ".tdms": "tdms",
}


_TOP_KEYS = (
    "name",
    "description",
    "origin",
    "rig",
    "recorded",
    "units",
    "columns",
    "csv",
    "sample_step",
    "valve_edges",
    "runs",
)


_REQUIRED_TOP = ("name", "description", "origin", "rig", "runs")


_RUN_KEYS = (
    "id",
    "kind",
    "file",
    "modulator",
    "controller",
    "notes",
    "columns",
    "units",
    "csv",
    "sample_step",
    "valve_edges",
)


_UNIT_KEYS = ("time", "pressure")


_NAME_RE = re.compile(r"[A-Za-z0-9._-]+")


_ID_RE = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,99}")


_ARROW_TYPES = {
    "t": pa.float64(),
    "p": pa.float64(),
    "valve": pa.int8(),
    "u": pa.float64(),
    "r": pa.float64(),
}


_QUANTITY = {
    "t": "time",
    "p": "pressure",
    "valve": "valve command",
    "u": "input fraction u",
    "r": "set-point r (pressure units)",
}


_NA_TOKENS = frozenset(
    [
        "",
        "#N/A",
        "#N/A N/A",
        "#NA",
        "-1.#IND",
        "-1.#QNAN",
        "-NaN",
        "-nan",
        "1.#IND",
        "1.#QNAN",
        "N/A",
        "NA",
        "NULL",
        "NaN",
        "n/a",
        "nan",
        "null",
    ]
)


_BATCH_ROWS = 1 << 19  # rows per Parquet / MATLAB chunk


_MAX_ROWS_LISTED = 5


# --------------------------------------------------------------------------- units


_UNIT_TOKEN = re.compile(r"[A-Za-z]+")


def unit_in_name(name: str | None) -> str | None:
    """The pressure unit a column's name states, as a separate word (``P_act_kPa``,
    ``pressure [psi]``, ``p_bar``), or None.

    Examples
    --------
    >>> [unit_in_name(n) for n in ("P_act_kPa", "Druck [mbar]", "pressure", "barometer")]
    ['kPa', 'mbar', None, None]
    """
    if not name:
        return None
    units = {u.lower(): u for u in PRESSURE_UNITS}
    found = {units[w.lower()] for w in _UNIT_TOKEN.findall(name) if w.lower() in units}
    return found.pop() if len(found) == 1 else None


#: Words naming a time unit in a column's name, and the unit (a key of :data:`TIME_UNITS`).
_TIME_WORDS: Mapping[str, str] = {
    "s": "s",
    "sec": "s",
    "secs": "s",
    "second": "s",
    "seconds": "s",
    "ms": "ms",
    "msec": "ms",
    "msecs": "ms",
    "millis": "ms",
    "millisecond": "ms",
    "milliseconds": "ms",
}


def time_unit_in_name(name: str | None) -> str | None:
    """The time unit a column's name states, as a separate word (``time_ms``, ``t[s]``,
    ``Time (ms)``, ``t_s``, ``millis``), or None.

    Examples
    --------
    >>> [time_unit_in_name(n) for n in ("time_ms", "t[s]", "Zeit (ms)", "millis", "time", "ts")]
    ['ms', 's', 'ms', 'ms', None, None]
    """
    if not name:
        return None
    found = {_TIME_WORDS[w.lower()] for w in _UNIT_TOKEN.findall(name) if w.lower() in _TIME_WORDS}
    return found.pop() if len(found) == 1 else None


def _to_seconds(t: npt.NDArray[np.float64], unit: str) -> npt.NDArray[np.float64]:
    return t / _DIVISORS[unit] if unit in _DIVISORS else t * TIME_UNITS[unit]


def _to_bar(p: Any, unit: str) -> Any:
    return p / _DIVISORS[unit] if unit in _DIVISORS else p * PRESSURE_UNITS[unit]
