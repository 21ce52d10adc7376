"""The day a session was recorded, from the data files' own headers (for ``spa init``).

Where a format carries one: a LabVIEW ``.lvm`` file header's ``Date`` (with ``Time``); a TDMS
file's ``wf_start_time`` (channel property) or a date-time file property; a MATLAB ``.mat``
file's header text (v5 and v7.3: ``Created on: Mon Mar  3 10:00:00 2025``). CSV and Parquet
files carry none. Only headers are read: a few kilobytes of each file.

>>> lvm_date("LabVIEW Measurement\\nDate\\t2025/03/04\\nTime\\t10:15:02.1\\n")
'2025-03-04'
>>> mat_header_date(b"MATLAB 5.0 MAT-file, Platform: GLNXA64, Created on: Mon Mar  3 10:00:00 2025")
'2025-03-03'
"""

from __future__ import annotations

import datetime
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

__all__ = ["header_date", "lvm_date", "mat_header_date", "session_date", "tdms_date"]

_HEAD = 1 << 16
_LVM_DATE = re.compile(r"^Date[\t,]\s*(\d{4})[/-](\d{1,2})[/-](\d{1,2})", re.M)
_MAT_DATE = re.compile(rb"Created on:\s+\w{3}\s+(\w{3})\s+(\d{1,2})\s+[\d:]+\s+(\d{4})")
_MONTHS = {m: i for i, m in enumerate("Jan Feb Mar Apr May Jun Jul Aug Sep Oct Nov Dec".split(), 1)}


def _iso(year: int, month: int, day: int) -> str | None:
    try:
        return datetime.date(year, month, day).isoformat()
    except ValueError:
        return None


def lvm_date(header: str) -> str | None:
    """The ``Date`` field of a LabVIEW measurement file's header (``YYYY/MM/DD``), as ISO."""
    m = _LVM_DATE.search(header)
    return _iso(int(m[1]), int(m[2]), int(m[3])) if m else None


def mat_header_date(head: bytes) -> str | None:
    """The ``Created on:`` date of a MAT file's header text (v5, or v7.3's user block)."""
    m = _MAT_DATE.search(head)
    if not m or m[1].decode() not in _MONTHS:
        return None
    return _iso(int(m[3]), _MONTHS[m[1].decode()], int(m[2]))


def _as_date(value: Any) -> str | None:
    """A date-time property (numpy datetime64, datetime, ISO text) as an ISO day."""
    import numpy as np

    if isinstance(value, np.datetime64):
        value = str(value.astype("datetime64[D]"))
    if isinstance(value, datetime.datetime | datetime.date):
        return value.isoformat()[:10]
    if isinstance(value, str):
        try:
            return datetime.date.fromisoformat(value.strip()[:10]).isoformat()
        except ValueError:
            return None
    return None


def tdms_date(path: str | Path) -> str | None:
    """The earliest ``wf_start_time`` of a TDMS file's channels, else a date-time file
    property (``DateTime``, ``datetime``), as an ISO day; its metadata alone is read."""
    from nptdms import TdmsFile

    meta = TdmsFile.read_metadata(path)
    found = [
        _as_date(c.properties.get("wf_start_time")) for g in meta.groups() for c in g.channels()
    ]
    found += [_as_date(v) for k, v in meta.properties.items() if k.lower() == "datetime"]
    found = sorted(d for d in found if d and d > "1904-01-01")  # LabVIEW's zero time: unset
    return found[0] if found else None


def header_date(path: str | Path) -> str | None:
    """The recording day a data file's header gives, or None (none, or not readable)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".lvm":
            with path.open("rb") as fh:
                return lvm_date(fh.read(_HEAD).decode("utf-8", "replace"))
        if suffix == ".mat":
            with path.open("rb") as fh:
                return mat_header_date(fh.read(512))
        if suffix == ".tdms":
            return tdms_date(path)
    except Exception:  # a damaged file: no date, the draft says so elsewhere
        return None
    return None


def session_date(folder: str | Path, files: Iterable[str]) -> tuple[str | None, str]:
    """The session's day: the earliest date among the files' headers, and where it is from.

    Returns
    -------
    date : str or None
        ISO day, or None when no file gives one.
    reason : str
        The file it comes from (and how many files gave a date), or why there is none.

    Examples
    --------
    >>> session_date(".", ["a.csv"])
    (None, 'no file header gives a date (a.csv)')
    """
    files = list(files)
    dates = {f: header_date(Path(folder) / f) for f in files}
    dated = sorted((d, f) for f, d in dates.items() if d)
    if not dated:
        listed = ", ".join(files[:3]) + (", ..." if len(files) > 3 else "")
        return None, f"no file header gives a date ({listed})"
    day, first = dated[0]
    more = f", the earliest of {len(dated)} files with one" if len(dated) > 1 else ""
    return day, f"from the header of {first}{more}"
