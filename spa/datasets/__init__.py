"""Dataset contract, validation and ingest of bench recordings (see ``raw/README.md``).

A dataset is a folder ``raw/<name>/`` holding ``dataset.yaml`` and the run files it names.
:func:`validate_dataset` checks the folder against the contract and returns every problem at
once; :func:`ingest_dataset` turns each run into one canonical Parquet run table, written by
:func:`write_run_table` and read back by :func:`read_run_table`.

The canonical run table has the columns ``t`` (s, float64), ``p`` (bar gauge, float64),
``valve`` (int8 in {0, 1}, when recorded) and ``u`` (input fraction in [0, 1], float64, when
recorded), in that order, and the run's description as JSON under the Parquet key-value
metadata key ``b"spa"``.

The folder follows the stages of that work: ``contract`` (the vocabulary: kinds, columns,
units), ``problems`` (what is wrong, with suggestions), ``spec`` (``dataset.yaml``),
``options`` (``columns:``, ``units:`` and ``csv:``, which a run may override key by key),
``clock`` (``sample_step``, for logs without time stamps, and ``valve_edges``),
``readers`` (one module per file family, each a ``Source``, in one table ``READERS``, and ``sniff``,
which guesses how a delimited file is written, for messages), ``checks``
(the data of one run, chunk by chunk), ``kind_check`` (a run's kind against its valve trace),
``supply`` (a supply pressure against the unit declared), ``runtable`` (the canonical Parquet
table) and ``ingest`` (validate and convert a whole folder).

Recordings are read in chunks (delimited text in line-aligned blocks, normalised as its
``csv:`` options say and parsed by ``pyarrow.csv``; Parquet by record batches), checked
chunk by chunk (carrying the last time stamp across chunks) and written batch by batch, so
the memory needed does not grow with the length of a recording.
MATLAB files are loaded whole by ``scipy.io.loadmat``.
"""

from __future__ import annotations

# The names imported here and left out of __all__ stay importable for the code that uses them.
# ruff: noqa: F401
from spa.datasets.checks import RunSummary
from spa.datasets.contract import (
    CANONICAL_COLUMNS,
    KINDS,
    META_KEY,
    MODULATED_KINDS,
    ORIGINS,
    P_MAX_BAR,
    P_MIN_BAR,
    PRESSURE_UNITS,
    RECOMMENDED_COLUMNS,
    REQUIRED_COLUMNS,
    RUN_TABLE_FORMAT,
    SPEC_FILE,
    TIME_UNITS,
)
from spa.datasets.contract import _to_bar as _to_bar
from spa.datasets.contract import _to_seconds as _to_seconds
from spa.datasets.ingest import check_dataset, ingest_dataset, validate_dataset
from spa.datasets.problems import DatasetError, Problem
from spa.datasets.readers.sniff import sniff_delimited
from spa.datasets.runtable import read_run_meta, read_run_table, read_runs, write_run_table
from spa.datasets.spec import DatasetSpec, RunEntry, find_datasets, load_spec

#: What a notebook user calls (the API reference lists these); the other names imported
#: above stay importable from here but are not presented as public API.
__all__ = [
    "CANONICAL_COLUMNS",
    "KINDS",
    "PRESSURE_UNITS",
    "TIME_UNITS",
    "DatasetError",
    "DatasetSpec",
    "Problem",
    "RunEntry",
    "check_dataset",
    "find_datasets",
    "ingest_dataset",
    "load_spec",
    "read_run_meta",
    "read_run_table",
    "read_runs",
    "validate_dataset",
    "write_run_table",
]
