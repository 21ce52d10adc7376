"""One reader per file family behind one dispatcher by file ending.

Each reader (a "source") opens one run's file and yields chunks of float columns; the
contract's ``format`` of a run (from its file ending, see ``spa.datasets.contract``) picks
it from :data:`_SOURCES`. Adding a format is one module here and one line in that table.
Every source is built as ``Source(path, options)``, ``options`` being the run's resolved
``csv:`` options (a mapping, or None) that only delimited text uses; it then offers
``columns`` (names in the file), ``chunks(names, as_text)`` and optionally ``check_types``,
``invalid`` and ``line_of``.
"""

from __future__ import annotations

from spa.datasets.readers.delimited import _CsvSource
from spa.datasets.readers.labview import _LvmSource
from spa.datasets.readers.matlab import _MatSource
from spa.datasets.readers.parquet import _ParquetSource
from spa.datasets.readers.tdms import _TdmsSource

_SOURCES = {
    "csv": _CsvSource,
    "parquet": _ParquetSource,
    "mat": _MatSource,
    "lvm": _LvmSource,
    "tdms": _TdmsSource,
}
