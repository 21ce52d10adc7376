"""Small, deterministic writers and logging shared by the workflow scripts."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, Final

from spa._yaml import read_yaml

if TYPE_CHECKING:
    import pandas as pd

    from spa.model.params import ValveParams

__all__ = [
    "PNG_DPI",
    "dump_yaml",
    "get_logger",
    "package_digest",
    "peak_rss_mib",
    "read_params",
    "read_yaml",
    "write_csv",
]

#: Resolution of the figures' PNG, dots per inch (print quality); the report shows them at
#: 100 CSS px per inch.
PNG_DPI = 200


def get_logger(
    name: str, log_path: str | Path | None = None, console: int = logging.WARNING
) -> logging.Logger:
    """Return a logger for a workflow script: everything to ``log_path``, and to stderr the
    messages of level ``console`` and above (warnings and errors; every message when there
    is no log file), so that the pipeline's console shows progress and problems, not each
    job's account of itself."""
    logger = logging.getLogger(f"spa.{name}")
    logger.setLevel(logging.INFO)
    logger.handlers.clear()
    fmt = logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s")
    handlers: list[logging.Handler] = [logging.StreamHandler()]
    if log_path is not None:
        handlers[0].setLevel(console)
        Path(log_path).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_path, mode="w"))
    for h in handlers:
        h.setFormatter(fmt)
        logger.addHandler(h)
    return logger


def package_digest() -> str:
    """SHA-256 (first 16 hex digits) of the source of every module of the ``spa`` package.

    The workflow passes it to every rule as a parameter, so that a change to the science
    in ``spa/`` reruns the jobs it may affect (Snakemake reruns a job whose parameters
    changed), while a change to comments or docs elsewhere in the repository does not.
    """
    import hashlib

    h = hashlib.sha256()
    root = Path(__file__).parent
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def dump_yaml(data: Any, stream: IO[str] | None = None, **options: Any) -> str | None:
    """``yaml.safe_dump`` for files people read and copy: never anchors or aliases.

    PyYAML writes a mapping or list met twice as ``&id001`` once and ``*id001`` after; a
    person copying one block (a controller's ``setting:`` into ``dataset.yaml``) gets an
    alias that means nothing there. Here every occurrence is written out in full; the output
    is otherwise that of ``yaml.safe_dump(data, stream, **options)``.

    Parameters
    ----------
    data : object
        Plain data (mappings, lists, str, int, float, bool, None).
    stream : file, optional
        Where to write; the text is returned when omitted.
    **options
        ``yaml.safe_dump``'s options (``sort_keys``, ``allow_unicode``, ``width``, ...).

    Returns
    -------
    str or None
        The YAML text when ``stream`` is None.

    Examples
    --------
    >>> shared = {"type": "pwm", "f_w": 20}
    >>> print(dump_yaml({"a": shared, "b": shared}, sort_keys=False), end="")
    a:
      type: pwm
      f_w: 20
    b:
      type: pwm
      f_w: 20
    """
    import yaml

    class _NoAliasDumper(yaml.SafeDumper):
        def ignore_aliases(self, data: Any) -> bool:
            return True

    return yaml.dump(data, stream, Dumper=_NoAliasDumper, **options)


def peak_rss_mib() -> float:
    """The largest resident set of this process so far, MiB (Linux: ``ru_maxrss`` in KiB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


CSV_FLOAT_FORMAT: Final = "%.10g"
"""How :func:`write_csv` writes a float: ten significant digits."""


def write_csv(df: pd.DataFrame, path: str | Path) -> None:
    """Write a table as CSV, floats to ten significant digits, no index (byte-stable).

    The bytes are those of ``df.to_csv(path, index=False, float_format="%.10g",
    lineterminator="\\n")``. A table of plain numbers and words (float64 without NaN,
    integer, boolean columns and strings that need no quotes, under such names: a figure's
    data, a run table) is formatted by one ``%``
    operation over the values of :data:`CSV_CHUNK_ROWS` rows at a time, about five times
    faster than pandas' writer (0.47 s against 2.6 s for a run table of 550 000 rows,
    ``benchmarks/bench_save.py``) in a few MB of memory; any other table goes through
    pandas.

    Examples
    --------
    >>> import pandas as pd, tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "t.csv"
    >>> write_csv(pd.DataFrame({"t": [0.1, 1 / 3], "n": [1, 2], "ok": [True, False]}), path)
    >>> print(path.read_text(), end="")
    t,n,ok
    0.1,1,True
    0.3333333333,2,False
    """
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    plain = _plain_columns(df)
    if plain is None:
        df.to_csv(path, index=False, float_format=CSV_FLOAT_FORMAT, lineterminator="\n")
        return
    with open(path, "w", encoding="utf-8", newline="") as out:
        out.writelines(_plain_lines(*plain))


CSV_CHUNK_ROWS: Final = 65_536
"""Rows :func:`write_csv` formats at a time: its memory stays that of a chunk (a few MB),
whatever the table's length."""


def _plain_words(column: Any) -> bool:
    """Whether a column of objects holds strings alone, none of which the CSV must quote."""
    import pandas as pd

    return all(type(word) is str and not set(word) & set(',"\n\r') for word in pd.unique(column))


def _plain_columns(df: pd.DataFrame) -> tuple[str, str, list[Any]] | None:
    """Header, row format and columns of a table of plain numbers and words (see
    :func:`write_csv`); None for any other table, which pandas writes."""
    import numpy as np
    import pandas as pd

    names = list(df.columns)
    if not names or df.columns.nlevels != 1 or df.columns.has_duplicates:
        return None
    if not all(isinstance(n, str) and n and not set(n) & set(',"\n\r') for n in names):
        return None
    formats = []
    for dtype in df.dtypes:
        if isinstance(dtype, pd.StringDtype) and len(names) > 1:
            formats.append("%s")  # pandas' default for strings; checked word by word below
        elif not isinstance(dtype, np.dtype):
            return None  # an extension type (nullable, categorical...): pandas' own rules
        elif dtype == np.float64:
            formats.append(CSV_FLOAT_FORMAT)
        elif dtype.kind in "iu":
            formats.append("%d")
        elif dtype.kind == "b" or (dtype.kind == "O" and len(names) > 1):
            formats.append("%s")  # a lone column of words: pandas quotes an empty one
        else:
            return None
    values = [
        df.iloc[:, j].to_numpy(dtype=object if isinstance(t, pd.StringDtype) else None)
        for j, t in enumerate(df.dtypes)
    ]
    if not all(_plain_words(v) for v in values if v.dtype.kind == "O"):
        return None
    if any(v.dtype == np.float64 and np.isnan(v).any() for v in values):
        return None  # pandas writes NaN as an empty field
    return ",".join(names) + "\n", ",".join(formats) + "\n", values


def _plain_lines(
    header: str, row: str, values: list[Any], chunk: int = CSV_CHUNK_ROWS
) -> Iterator[str]:
    """The CSV's text, ``chunk`` rows at a time: each chunk one ``%`` over its values."""
    import numpy as np

    yield header
    rows = len(values[0])
    for start in range(0, rows, chunk):
        part = [v[start : start + chunk] for v in values]
        table = np.empty((len(part[0]), len(part)), dtype=object)
        for j, v in enumerate(part):
            table[:, j] = v.astype(object)  # Python floats, ints and bools, row by row below
        yield (row * len(table)) % tuple(table.ravel().tolist())


def read_params(path: str | Path) -> ValveParams:
    """The valve parameters of a ``params.yaml`` written by the identify stage.

    Raises
    ------
    ValueError
        If a parameter is missing or invalid; the message names the file and the parameter.
    """
    from spa.identification import load_params

    content = read_yaml(path)
    if not isinstance(content, dict):
        raise ValueError(f"{path}: expected a mapping of parameters, got {type(content).__name__}")
    try:
        return load_params(content)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
