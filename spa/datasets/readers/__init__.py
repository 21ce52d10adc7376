"""One reader per file family, in one table from the format to its reader.

Each reader (a :class:`~spa.datasets.readers.base.Source`) opens one run's file and yields
chunks of float columns; the contract's ``format`` of a run (from its file ending,
:data:`spa.datasets.contract._FORMATS`) picks it from :data:`READERS`. Every reader is built
as ``Reader(path, options)``, ``options`` being the run's resolved ``csv:`` options (a
mapping, or None) that only delimited text uses, and offers :attr:`~Source.columns` and
:meth:`~Source.chunks`; the other hooks (``resolve``, ``describe``, ``check_types``,
``line_of``, ``what``, ``sep``, ``invalid``) have defaults in :class:`Source` that a format
overrides where it knows more.

Adding a format is one module here (a ``Source`` subclass) and one line in :data:`READERS`,
plus its file ending in the contract's ``_FORMATS`` (``tests/test_readers_table.py`` does
both for a toy format).
"""

from __future__ import annotations

from spa.datasets.readers.base import Source
from spa.datasets.readers.delimited import _CsvSource
from spa.datasets.readers.labview import _LvmSource
from spa.datasets.readers.matlab import _MatSource
from spa.datasets.readers.parquet import _ParquetSource
from spa.datasets.readers.tdms import _TdmsSource

__all__ = ["READERS", "Source"]

#: Format (the contract's name for a file ending) -> its reader.
READERS: dict[str, type[Source]] = {
    "csv": _CsvSource,
    "parquet": _ParquetSource,
    "mat": _MatSource,
    "lvm": _LvmSource,
    "tdms": _TdmsSource,
}
