"""spa.io.write_csv: the bytes of pandas' writer (``%.10g``, no index), by a faster path."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from spa.io import _plain_columns, _plain_lines, write_csv

SPECIAL = [0.0, -0.0, np.inf, -np.inf, 1e-300, 5e-324, 1e20, 123456789012.0, 1 / 3, 0.1, 1e-5]


def _pandas(df: pd.DataFrame) -> bytes:
    return df.to_csv(index=False, float_format="%.10g", lineterminator="\n").encode()


def _ours(df: pd.DataFrame) -> bytes:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "t.csv"
        write_csv(df, path)
        return path.read_bytes()


floats = st.one_of(st.floats(allow_nan=False, width=64), st.sampled_from(SPECIAL))
columns = st.one_of(
    st.lists(floats, min_size=0, max_size=30).map(lambda v: np.array(v, dtype=np.float64)),
    st.lists(st.integers(-(2**62), 2**62), max_size=30).map(lambda v: np.array(v, dtype=np.int64)),
    st.lists(st.booleans(), max_size=30).map(lambda v: np.array(v, dtype=bool)),
    st.lists(st.text(alphabet="ab -_.0µ", max_size=4), max_size=30).map(
        lambda v: np.array(v, dtype=object)
    ),
)
words = st.lists(st.text(alphabet='ab ,"\n\r', max_size=3), min_size=1, max_size=10)


@settings(max_examples=200, deadline=None)
@given(st.lists(columns, min_size=1, max_size=5), st.data())
def test_bytes_are_pandas_bytes(cols: list[np.ndarray], data: st.DataObject) -> None:
    rows = min(len(c) for c in cols)
    df = pd.DataFrame({f"c{j}": c[:rows] for j, c in enumerate(cols)})
    assert (_plain_columns(df) is None) == (len(cols) == 1 and cols[0].dtype == object)
    assert _ours(df) == _pandas(df)


@settings(max_examples=100, deadline=None)
@given(words)
def test_words_that_need_quotes_are_quoted_as_pandas_quotes_them(values: list[str]) -> None:
    df = pd.DataFrame({"run": np.array(values, dtype=object), "x": np.arange(len(values)) / 3})
    plain = not any(set(v) & set(',"\n\r') for v in values)
    assert (_plain_columns(df) is not None) == plain
    assert _ours(df) == _pandas(df)


def test_tables_the_fast_path_leaves_to_pandas_are_written_as_pandas_writes_them() -> None:
    tables = {
        "NaN": pd.DataFrame({"x": [1.0, np.nan]}),
        "text": pd.DataFrame({"run": ["a,b", 'say "hi"'], "x": [1.0, 2.0]}),
        "words and a missing one": pd.DataFrame({"run": ["a", None], "x": [1.0, 2.0]}),
        "one column of words": pd.DataFrame({"run": ["a", ""]}),
        "name with a comma": pd.DataFrame({"a,b": [1.0]}),
        "nullable": pd.DataFrame({"n": pd.array([1, None], dtype="Int64")}),
        "float32": pd.DataFrame({"x": np.array([0.1, 1 / 3], dtype=np.float32)}),
        "no column": pd.DataFrame(),
    }
    for name, df in tables.items():
        assert _plain_columns(df) is None, name
        assert _ours(df) == _pandas(df), name


def test_an_empty_table_keeps_its_header() -> None:
    df = pd.DataFrame({"t": np.array([], dtype=float), "n": np.array([], dtype=np.int64)})
    assert _ours(df) == _pandas(df) == b"t,n\n"


def test_a_table_longer_than_a_chunk_is_written_chunk_by_chunk_to_the_same_bytes() -> None:
    n = 1000
    df = pd.DataFrame({"t": np.arange(n) / 7.0, "valve": np.arange(n) % 2, "run": "a"})
    plain = _plain_columns(df)
    assert plain is not None
    whole = "".join(_plain_lines(*plain, chunk=n))
    for chunk in (1, 7, 999, 1000, 5000):
        assert "".join(_plain_lines(*plain, chunk=chunk)) == whole
    assert whole.encode() == _pandas(df)
