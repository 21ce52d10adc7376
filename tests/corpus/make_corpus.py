"""Rebuild the dataset corpus used by tests/test_datasets.py.

    .venv/bin/python tests/corpus/make_corpus.py

``good/<name>/`` holds valid datasets. ``bad/<case>/`` holds one malformed dataset per
problem, with ``expected.txt`` listing (one per line) substrings that the messages of
``spa validate`` must contain. The files are committed; rerun this script after changing a
case, and check the diff.
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import scipy.io
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/, for file_writers
from file_writers import (
    dspace_recording,
    to_savemat,
    write_lvm,
    write_mat73,
    write_tdms,
)

HERE = Path(__file__).resolve().parent
RIG = {
    "valve": "3/2 on/off solenoid valve",
    "actuator": "PneuNet bending actuator",
    "sensors": "gauge pressure transducer 0-2 bar",
    "controller": "Arduino Due, 1 kHz",
}
N = 20


def _write_yaml(folder: Path, doc: dict[str, Any]) -> None:
    text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=100)
    (folder / "dataset.yaml").write_text(text)


def _spec(folder_name: str, runs: list[dict[str, Any]], **extra: Any) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "name": folder_name,
        "description": f"corpus case {folder_name}",
        "origin": "bench",
        "rig": RIG,
    }
    doc.update(extra)
    doc["runs"] = runs
    return doc


def _frame(n: int = N, u: bool = False) -> pd.DataFrame:
    t = np.round(np.arange(n) * 0.001, 6)
    valve = (np.arange(n) // 5 % 2 == 0).astype(int)
    p = np.round(0.8 * (1 - np.exp(-t / 0.05)), 6)
    df = pd.DataFrame({"t": t, "p": p, "valve": valve})
    if u:
        df["u"] = np.round(np.minimum(np.arange(n) // 5 * 0.25, 1.0), 6)
    return df


def _csv(folder: Path, name: str, df: pd.DataFrame) -> None:
    df.to_csv(folder / name, index=False, lineterminator="\n")


CHARGE = {"id": "charge1", "kind": "charge", "file": "charge1.csv"}
STAIR = {
    "id": "stair1",
    "kind": "staircase",
    "file": "stair1.csv",
    "modulator": {"type": "pwm", "f_w": 20},
}


def _case(folder: Path, runs: list[dict[str, Any]] | None = None, df: pd.DataFrame | None = None,
          **extra: Any) -> None:
    """A dataset with one charge run (or ``runs``) whose CSV holds ``df``."""
    runs = [dict(CHARGE)] if runs is None else runs
    _write_yaml(folder, _spec(folder.name, runs, **extra))
    for run in runs:
        name = run.get("file")
        if isinstance(name, str) and name.endswith(".csv") and "/" not in name:
            data = df if df is not None else _frame(u=run.get("kind") in ("staircase", "sine"))
            _csv(folder, name, data)


def _raw(folder: Path, yaml_text: str) -> None:
    (folder / "dataset.yaml").write_text(yaml_text)
    _csv(folder, "charge1.csv", _frame())


def _mat_case(folder: Path, variables: dict[str, Any], kind: str = "sine") -> None:
    run = {"id": "m1", "kind": kind, "file": "m1.mat", "modulator": {"type": "dsm", "period": 0.02}}
    _write_yaml(folder, _spec(folder.name, [run]))
    scipy.io.savemat(folder / "m1.mat", variables)


def _good(folder: Path) -> None:
    """Every kind, every modulator, every reader, renamed columns, ms and kPa."""
    n = 400
    t_ms = np.arange(n) * 1.0
    t = t_ms / 1000
    xi = np.clip(np.floor(t / 0.1) * 0.25, 0, 1)
    valve = (np.arange(n) % 20 < 10).astype(np.int8)
    p_kpa = np.round(60 * (1 - np.exp(-t / 0.08)), 5)
    runs = [
        {"id": "charge", "kind": "charge", "file": "csv/charge.csv",
         "notes": "valve opened at t = 0"},
        {"id": "discharge", "kind": "discharge", "file": "csv/discharge.csv"},
        {"id": "pulse-10ms", "kind": "pulse", "file": "csv/pulse.csv"},
        {"id": "stair_pwm", "kind": "staircase", "file": "stair_pwm.parquet",
         "modulator": {"type": "pwm", "f_w": 20}},
        {"id": "sine_ipfm", "kind": "sine", "file": "sine_ipfm.mat",
         "modulator": {"type": "ipfm", "t_h": 0.02}},
        {"id": "chirp_iipfm", "kind": "chirp", "file": "chirp_iipfm.csv",
         "modulator": {"type": "iipfm", "t_l": 0.02, "gain": 1.15}},
        {"id": "stair_dsm", "kind": "staircase", "file": "stair_dsm.csv",
         "modulator": {"type": "dsm", "period": 0.02}},
        {"id": "loop_iipfm", "kind": "closed_loop", "file": "loop_iipfm.csv",
         "modulator": {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
         "controller": {"kp": 4.0, "ki": 4.5, "dt": 0.001}},
    ]
    doc = _spec(folder.name, runs, units={"time": "ms", "pressure": "kPa"},
                columns={"t": "time_ms", "p": "P_kPa", "valve": "V", "u": "xi", "r": "R_kPa"})
    doc["description"] = "Small valid dataset exercising every kind, modulator and file format."
    _write_yaml(folder, doc)
    (folder / "csv").mkdir()
    frame = pd.DataFrame({"time_ms": t_ms, "P_kPa": p_kpa, "V": valve})
    _csv(folder, "csv/charge.csv", frame)
    _csv(folder, "csv/discharge.csv", frame.assign(P_kPa=p_kpa[::-1].copy(), V=0))
    _csv(folder, "csv/pulse.csv", frame)
    with_u = frame.assign(xi=xi)
    table = pa.Table.from_pandas(with_u, preserve_index=False)
    pq.write_table(table, folder / "stair_pwm.parquet")
    scipy.io.savemat(folder / "sine_ipfm.mat",
                     {"time_ms": t_ms, "P_kPa": p_kpa, "V": valve.astype(float), "xi": xi})
    _csv(folder, "chirp_iipfm.csv", with_u)
    _csv(folder, "stair_dsm.csv", with_u)
    _csv(folder, "loop_iipfm.csv", with_u.assign(R_kPa=np.where(t < 0.2, 20.0, 50.0)))


def _multi(folder: Path) -> None:
    runs = [
        {"id": "charge1", "kind": "charge", "file": "charge1.csv"},
        {"id": "pulse1", "kind": "pulse", "file": "pulse1.csv"},
        {"id": "sine1", "kind": "sin", "file": "sine1.csv",
         "modulator": {"type": "pwm", "f_w": 20}},
    ]
    doc = _spec(folder.name, runs)
    doc["orign"] = doc.pop("origin")
    _write_yaml(folder, doc)
    bad = _frame().astype({"p": object})
    bad.loc[4, "p"] = "abc"
    _csv(folder, "charge1.csv", bad)
    back = _frame()
    back.loc[9, "t"] = 0.002
    back.loc[3, "valve"] = 3
    _csv(folder, "pulse1.csv", back)
    _csv(folder, "sine1.csv", _frame(u=True))


def _with(df: pd.DataFrame, col: str, row: int, value: Any) -> pd.DataFrame:
    """``df`` with ``df[col]`` at data row ``row`` (1-based) set to ``value``."""
    out = df.astype({col: object})
    out.loc[row - 1, col] = value
    return out


def _truncated_csv(folder: Path) -> None:
    _case(folder)
    path = folder / "charge1.csv"
    data = path.read_bytes()
    path.write_bytes(data[: data.rstrip(b"\n").rfind(b",")])  # cut the last line mid-row


def _parquet_case(folder: Path, table: pa.Table, truncate: bool = False) -> None:
    run = {"id": "pq1", "kind": "charge", "file": "pq1.parquet"}
    _write_yaml(folder, _spec(folder.name, [run]))
    pq.write_table(table, folder / "pq1.parquet")
    if truncate:
        data = (folder / "pq1.parquet").read_bytes()
        (folder / "pq1.parquet").write_bytes(data[: len(data) // 2])


def _symlink(folder: Path) -> None:
    _case(folder, runs=[{"id": "charge1", "kind": "charge", "file": "charge1.csv"}])
    (folder / "charge1.csv").unlink()
    (folder / "charge1.csv").symlink_to("../../good/spa_good/csv/charge.csv")


def _v73(folder: Path) -> None:
    _mat_case(folder, {"t": np.arange(3.0)})
    header = bytearray(b" " * 128)
    header[:19] = b"MATLAB 7.3 MAT-file"
    header[124:128] = b"\x00\x02IM"
    (folder / "m1.mat").write_bytes(bytes(header) + b"\x89HDF\r\n\x1a\n" + b"\x00" * 64)


def _numbers(df: pd.DataFrame, sep: str = ",", decimal: str = ".") -> list[str]:
    """Rows of ``df`` as text, each number as its shortest repr (``decimal`` as its mark)."""
    cells = df.map(lambda v: repr(float(v)) if isinstance(v, float) else str(v))
    if decimal != ".":
        cells = cells.map(lambda v: v.replace(".", decimal))
    return [sep.join(row) for row in cells.itertuples(index=False)]


EU_PREAMBLE = ["Prüfstand: Ventil 3/2, Aktor PneuNet", "Datum: 23.11.2026", "Raumtemperatur: 21 °C"]
EU_CSV = {"sep": ";", "decimal": ",", "encoding": "cp1252", "skip_rows": 3, "units_row": True}
EU_COLUMNS = {"t": "Zeit", "p": "Druck", "valve": "Ventil"}
EU_RUN = {"id": "pulse_eu", "kind": "pulse", "file": "pulse_eu.csv"}


def _eu_frame(n: int = 400) -> pd.DataFrame:
    df = _frame(n)
    return df.assign(oil=np.round(21.0 + 0.01 * np.arange(n), 2))


def _eu_file(folder: Path, name: str, df: pd.DataFrame) -> None:
    """A European spreadsheet export: cp1252, 3 lines of metadata, a units row, ';' and ','."""
    lines = [*EU_PREAMBLE, "Zeit;Druck;Ventil;Öltemperatur", "s;bar;-;°C"]
    text = "\r\n".join([*lines, *_numbers(df, ";", ",")]) + "\r\n"
    (folder / name).write_bytes(text.encode("cp1252"))


def _european(folder: Path) -> None:
    """The same pulse as a European CSV and as a plain CSV (the run overrides csv:, columns:)."""
    df = _eu_frame()
    plain = {"id": "pulse_plain", "kind": "pulse", "file": "pulse_plain.csv",
             "columns": {"t": "t", "p": "p", "valve": "valve"},
             "csv": {"sep": ",", "decimal": ".", "encoding": "utf-8", "skip_rows": 0,
                     "units_row": False}}
    _write_yaml(folder, _spec(folder.name, [EU_RUN, plain], columns=EU_COLUMNS, csv=EU_CSV))
    _eu_file(folder, "pulse_eu.csv", df)
    text = "\n".join(["t,p,valve,oil", *_numbers(df)]) + "\n"
    (folder / "pulse_plain.csv").write_text(text)


def _commented_tsv(folder: Path) -> None:
    """Tab-separated (the default of .tsv) with '#' comment lines above and among the data."""
    run = {"id": "charge_tsv", "kind": "charge", "file": "charge.tsv"}
    _write_yaml(folder, _spec(folder.name, [run], csv={"comment": "#"}))
    rows = _numbers(_frame(400), "\t")
    rows.insert(200, "# valve re-seated here, recording went on")
    text = "\n".join(["# logger v2.1", "# 1 kHz", "t\tp\tvalve", *rows, "# end"]) + "\n"
    (folder / "charge.tsv").write_text(text)


def _whitespace_txt(folder: Path) -> None:
    """Columns aligned by runs of spaces (and a tab), as a fixed-width text export."""
    run = {"id": "discharge_txt", "kind": "discharge", "file": "discharge.txt"}
    _write_yaml(folder, _spec(folder.name, [run], csv={"sep": "whitespace"}))
    df = _frame(400).assign(p=lambda d: d["p"].to_numpy()[::-1])
    rows = [" ".join(f"{c:>12}" for c in row.split(",")) for row in _numbers(df)]
    rows[7] = rows[7].replace(" ", "\t", 3)
    text = "\n".join([f"{'t':>12} {'p':>12} {'valve':>12}", *rows]) + "\n"
    (folder / "discharge.txt").write_text(text)


def _per_run(folder: Path) -> None:
    """Runs whose files name columns and units differently (run-level columns:, units:)."""
    df = _frame(400, u=True)
    runs = [
        {"id": "stair_ms", "kind": "staircase", "file": "stair_ms.csv",
         "modulator": {"type": "pwm", "f_w": 20}},
        {"id": "stair_s", "kind": "staircase", "file": "stair_s.csv",
         "modulator": {"type": "pwm", "f_w": 20},
         "columns": {"t": "time", "p": "pressure", "u": "duty"},
         "units": {"time": "s", "pressure": "bar"}},
    ]
    _write_yaml(folder, _spec(folder.name, runs, units={"time": "ms", "pressure": "kPa"},
                              columns={"t": "t_ms", "p": "p_kPa"}))
    ms = df.assign(t=np.round(df["t"] * 1000, 6), p=np.round(df["p"] * 100, 6))
    _csv(folder, "stair_ms.csv", ms.rename(columns={"t": "t_ms", "p": "p_kPa"}))
    _csv(folder, "stair_s.csv", df.rename(columns={"t": "time", "p": "pressure", "u": "duty"}))


def _eu_case(folder: Path, csv: dict[str, Any] | None) -> None:
    extra = {"csv": csv} if csv is not None else {}
    _write_yaml(folder, _spec(folder.name, [EU_RUN], columns=EU_COLUMNS, **extra))
    _eu_file(folder, "pulse_eu.csv", _eu_frame(40))


def _preamble(folder: Path, units_row: bool = False) -> None:
    _case(folder, runs=[CHARGE])
    lines = ["t,p,valve", *_numbers(_frame())]
    if units_row:
        lines.insert(1, "s,bar,-")
    else:
        lines[:0] = ["Operator: A. Smith", "Sensor: 0-2 bar, serial 1234"]
    (folder / "charge1.csv").write_text("\n".join(lines) + "\n")


def _dspace_ambiguous(folder: Path) -> None:
    _mat_case(folder, {})
    t = np.arange(N) * 0.001
    rec = dspace_recording("time", t, {"Model/A/p": t, "Model/B/p": t, "Model/A/ux": t})
    scipy.io.savemat(folder / "m1.mat", {"rec": to_savemat(rec)})


def _lvm_segments_differ(folder: Path) -> None:
    _write_yaml(folder, _spec(folder.name, [{**CHARGE, "id": "r", "file": "r.lvm"}]))
    df = _frame()
    first = {"X_Value": df["t"].to_numpy()[:10], "p": df["p"].to_numpy()[:10]}
    second = {"X_Value": df["t"].to_numpy()[10:], "p": df["p"].to_numpy()[10:],
              "valve": df["valve"].to_numpy()[10:]}
    write_lvm(folder / "r.lvm", [[first], [second]])


def _good_bench(folder: Path) -> None:
    """The bench formats: dSpace MAT, MAT v7.3 in psi, LabVIEW .lvm with ',' and TDMS."""
    n = 300
    t = np.round(np.arange(n) * 0.001, 6)
    p = np.round(8 * (1 - np.exp(-t / 0.08)), 5)  # psi
    valve = (np.arange(n) % 20 < 10).astype(float)
    u = np.clip(np.floor(t / 0.1) * 0.25, 0, 1)
    mod = {"type": "pwm", "f_w": 20}
    runs = [{"id": f, "kind": "staircase", "file": f, "modulator": mod}
            for f in ("dspace.mat", "v73.mat", "rec.lvm", "rec.tdms")]
    doc = _spec(folder.name, runs, units={"time": "s", "pressure": "psi"},
                columns={"p": "p_act"})
    doc["description"] = "Small valid dataset in the bench formats: dSpace, v7.3, LVM, TDMS."
    _write_yaml(folder, doc)
    sig = {"Platform/Model Root/Sensors/p_act": p, "Platform/Model Root/Out/valve": valve,
           "Platform/Model Root/In/u": u}
    scipy.io.savemat(folder / "dspace.mat", {"rec": to_savemat(dspace_recording("t", t, sig))})
    write_mat73(folder / "v73.mat", {"t": t, "p_act": p, "valve": valve.astype(bool), "u": u})
    cols = {"X_Value": t, "p_act": p, "valve": valve, "u": u}
    write_lvm(folder / "rec.lvm", [[{k: v[:100] for k, v in cols.items()}],
                                   [{k: v[100:] for k, v in cols.items()}]])
    write_tdms(folder / "rec.tdms", "Measured", [{"p_act": p, "valve": valve, "u": u}],
               waveform=(0.0, 0.001))


F = _frame()
FU = _frame(u=True)
T = np.arange(N) * 0.001

# case name -> (builder, expected substrings)
BAD: dict[str, tuple[Callable[[Path], None], list[str]]] = {
    "missing_yaml": (lambda d: _csv(d, "charge1.csv", F), ["missing dataset.yaml"]),
    "unparsable_yaml": (
        lambda d: _raw(d, "name: unparsable_yaml\nruns: [\n  - {id: a, kind: charge\n"),
        ["cannot parse YAML at line"],
    ),
    "yaml_not_mapping": (lambda d: _raw(d, "- charge1.csv\n"), ["expected a mapping with keys"]),
    "duplicate_yaml_key": (
        lambda d: _raw(d, "name: duplicate_yaml_key\nname: again\n"),
        ["cannot parse YAML", "found duplicate key 'name'"],
    ),
    "unknown_key_typo": (
        lambda d: _write_yaml(d, {("descripton" if k == "description" else k): v
                                  for k, v in _spec(d.name, [CHARGE]).items()})
        or _csv(d, "charge1.csv", F),
        ["unknown key 'descripton' (did you mean 'description'?)",
         "missing required key 'description'"],
    ),
    "missing_required_key": (
        lambda d: _write_yaml(d, {k: v for k, v in _spec(d.name, [CHARGE]).items()
                                  if k != "origin"}) or _csv(d, "charge1.csv", F),
        ["missing required key 'origin'"],
    ),
    "name_mismatch": (lambda d: _case(d, name="other_name"),
                      ["name 'other_name' differs from the folder name 'name_mismatch'"]),
    "bad_name": (lambda d: _case(d, name="my data!"),
                 ["name 'my data!' must be a string of letters, digits"]),
    "bad_origin": (
        lambda d: _case(d, origin="synthetc"),
        ["origin 'synthetc' is not one of bench, synthetic (did you mean 'synthetic'?)"],
    ),
    "bad_rig": (lambda d: _case(d, rig="an Arduino"), ["rig must be a mapping"]),
    "bad_units": (
        lambda d: _case(d, units={"time": "sec", "pressure": "kpa"}),
        ["units.time: time unit 'sec' is not one of s, ms",
         "pressure unit 'kpa' is not one of bar, mbar, kPa, psi (did you mean 'kPa'?)"],
    ),
    "unknown_units_key": (lambda d: _case(d, units={"presure": "kPa"}),
                          ["unknown key 'presure' (did you mean 'pressure'?)"]),
    "bad_columns_key": (lambda d: _case(d, columns={"valv": "V"}),
                        ["unknown canonical column 'valv' (did you mean 'valve'?)"]),
    "columns_duplicate": (lambda d: _case(d, columns={"p": "x", "u": "x"}),
                          ["file column 'x' is used for several canonical columns"]),
    "unknown_kind": (
        lambda d: _case(d, runs=[{**CHARGE, "kind": "stair"}]),
        ["runs[0].kind [run 'charge1']: unknown kind 'stair'", "(did you mean 'staircase'?)"],
    ),
    "unknown_modulator_type": (
        lambda d: _case(d, runs=[{**STAIR, "modulator": {"type": "pfm", "f_w": 20}}]),
        ["runs[0].modulator [run 'stair1']: unknown modulator type 'pfm'",
         "(did you mean 'ipfm'?)"],
    ),
    "bad_modulator_settings": (
        lambda d: _case(d, runs=[{**STAIR, "modulator": {"type": "pwm", "f_w": -5}}]),
        ["bad modulator settings: pwm: setting 'f_w' must be finite and > 0"],
    ),
    "missing_modulator_setting": (
        lambda d: _case(d, runs=[{**STAIR, "modulator": {"type": "ipfm", "gain": 1.2}}]),
        ["ipfm: missing setting 't_h'"],
    ),
    "modulator_setting_typo": (
        lambda d: _case(d, runs=[{**STAIR, "modulator": {"type": "ipfm", "th": 0.02}}]),
        ["unknown ipfm setting 'th' (did you mean 't_h'?)"],
    ),
    "missing_modulator": (
        lambda d: _case(d, runs=[{k: v for k, v in STAIR.items() if k != "modulator"}]),
        ["runs[0].modulator [run 'stair1']: a staircase run needs a modulator"],
    ),
    "duplicate_run_id": (
        lambda d: _case(d, runs=[dict(CHARGE), dict(CHARGE)]),
        ["runs[1].id [run 'charge1']: duplicate run id 'charge1'"],
    ),
    "bad_run_id": (
        lambda d: _case(d, runs=[{**CHARGE, "id": "run 1/a"}]),
        ["id 'run 1/a' is not filename-safe"],
    ),
    "numeric_run_id": (
        lambda d: _case(d, runs=[{**CHARGE, "id": 7}]),
        ["runs[0].id: id must be a string (quote it in YAML: id: '7')"],
    ),
    "unknown_run_key": (
        lambda d: _case(d, runs=[{**STAIR, "modulater": STAIR["modulator"]}]),
        ["unknown key 'modulater' (did you mean 'modulator'?)"],
    ),
    "missing_run_keys": (
        lambda d: _case(d, runs=[{"id": "charge1", "kind": "charge"}]),
        ["runs[0] [run 'charge1']: missing required key 'file'"],
    ),
    "runs_empty": (lambda d: _case(d, runs=[]), ["runs is empty"]),
    "path_absolute": (
        lambda d: _case(d, runs=[{**CHARGE, "file": "/etc/hostname.csv"}]),
        ["file path '/etc/hostname.csv' is absolute"],
    ),
    "path_dotdot": (
        lambda d: _case(d, runs=[{**CHARGE, "file": "../../good/spa_good/csv/charge.csv"}]),
        ["leaves the dataset folder through '..'"],
    ),
    "path_backslash": (
        lambda d: _case(d, runs=[{**CHARGE, "file": "csv\\charge1.csv"}]),
        ["use '/' between folders"],
    ),
    "path_symlink": (_symlink, ["outside the dataset folder (a symlink pointing out?)"]),
    "missing_file": (
        lambda d: _case(d, runs=[{**CHARGE, "file": "nothere.csv"}])
        or (d / "nothere.csv").unlink(),
        ["runs[0].file [run 'charge1']: file 'nothere.csv' not found"],
    ),
    "unsupported_extension": (
        lambda d: _case(d, runs=[{**CHARGE, "file": "charge1.xlsx"}])
        or (d / "charge1.xlsx").write_bytes(b"PK\x03\x04"),
        ["unsupported file type '.xlsx'", "expected one of .csv, .parquet, .mat"],
    ),
    "empty_file": (
        lambda d: _case(d) or (d / "charge1.csv").write_bytes(b""),
        ["charge1.csv [run 'charge1']: file is empty (0 bytes)"],
    ),
    "header_only": (lambda d: _case(d, df=F.iloc[:0]),
                    ["0 data row(s); a run needs at least 2 samples"]),
    "one_row": (lambda d: _case(d, df=F.iloc[:1]),
                ["1 data row(s); a run needs at least 2 samples"]),
    "truncated_csv": (
        _truncated_csv,
        [f"[run 'charge1', line {N + 1}]: malformed line",
         "expected 3 comma-separated fields, got 2"],
    ),
    "unreadable_csv_header": (
        lambda d: _case(d) or (d / "charge1.csv").write_bytes(b"\xff\xfe\x00t\x00,\n1,2\n"),
        ["are not utf-16 text (truncated data)", "starts with a byte-order mark of that encoding"],
    ),
    "csv_utf16_no_bom": (
        lambda d: _case(d)
        or (d / "charge1.csv").write_bytes("t,p,valve\n0,0,1\n1,1,1\n".encode("utf-16-le")),
        ["UTF-16 text without a byte-order mark"],
    ),
    "csv_cr_line_ends": (
        lambda d: _case(d)
        or (d / "charge1.csv").write_bytes(b"t,p,valve\r0,0,1\r0.001,0.1,1\r"),
        ["the lines end in CR alone (old Mac OS text)"],
    ),
    "truncated_parquet": (
        lambda d: _parquet_case(d, pa.Table.from_pandas(F, preserve_index=False), truncate=True),
        ["pq1.parquet [run 'pq1']: unreadable Parquet file (truncated or damaged?)"],
    ),
    "parquet_text_column": (
        lambda d: _parquet_case(d, pa.table({"t": T, "p": ["0.1"] * 5 + ["high"] + ["0.2"] * 14})),
        ["column 'p', row 6]: non-numeric value; expected a number"],
    ),
    "parquet_bad_type": (
        lambda d: _parquet_case(d, pa.table({"t": T, "p": pa.array([[1.0]] * N)})),
        ["column 'p']: column has Parquet type list<", "expected numbers"],
    ),
    "parquet_missing_column": (
        lambda d: _parquet_case(d, pa.table({"time": T, "p": np.zeros(N)})),
        ["missing column 't'", "a charge run needs time (t)", "the file has 'time', 'p'"],
    ),
    "unreadable_mat": (
        lambda d: _mat_case(d, {}) or (d / "m1.mat").write_bytes(b"not a MATLAB file " * 20),
        ["m1.mat [run 'm1']: unreadable MATLAB file"],
    ),
    "mat_v73_damaged": (_v73, ["m1.mat [run 'm1']: unreadable MATLAB v7.3 (HDF5) file"]),
    "mat_v73_cell": (
        lambda d: _mat_case(d, {})
        or write_mat73(d / "m1.mat", {"t": T, "p": {"raw": T}, "u": "x"}),
        ["column 'p']: MATLAB variable 'p' is a struct (fields 'raw'); name one of its fields",
         "column 'u']: MATLAB variable 'u' holds char, not numbers"],
    ),
    "dspace_ambiguous_signal": (
        _dspace_ambiguous,
        ["column 'p']: signal name 'p' is ambiguous: it ends 'Model/A/p', 'Model/B/p'; give the "
         "full signal name under columns: in dataset.yaml",
         "column 'u']: missing signal 'u': a sine run needs input fraction u (u); the file holds "
         "the variables 'rec', the dSpace signals 'time', 'Model/A/p', 'Model/B/p', 'Model/A/ux' "
         "(did you mean 'ux'?)"],
    ),
    "lvm_segments_differ": (
        _lvm_segments_differ,
        ["r.lvm [run 'r']: segment 2 names the columns ['X_Value', 'p', 'valve'], segment 1 "
         "['X_Value', 'p']; segments are joined and need the same channels"],
    ),
    "tdms_no_timing": (
        lambda d: _write_yaml(d, _spec(d.name, [{**CHARGE, "file": "r.tdms"}]))
        or write_tdms(d / "r.tdms", "G", [{"p": F["p"].to_numpy()}]),
        ["r.tdms [run 'charge1', column 't']: missing LabVIEW channel 't': a charge run needs "
         "time (t); the file has the channels 'G/p' and no waveform timing"],
    ),
    "missing_mat_variable": (
        lambda d: _mat_case(d, {"t": T, "p": np.zeros(N)}),
        ["column 'u']: missing MATLAB variable 'u': a sine run needs input fraction u (u)"],
    ),
    "mat_not_vector": (
        lambda d: _mat_case(d, {"t": T, "p": np.zeros((N, 2)), "u": np.zeros(N)}),
        ["MATLAB variable 'p' has shape 20×2; expected a vector"],
    ),
    "mat_lengths": (
        lambda d: _mat_case(d, {"t": T, "p": np.zeros(N - 1), "u": np.zeros(N)}),
        ["MATLAB variables have different lengths (t: 20, p: 19, u: 20)"],
    ),
    "mat_text_variable": (
        lambda d: _mat_case(d, {"t": T, "p": "high", "u": np.zeros(N)}),
        ["column 'p']: MATLAB variable 'p' holds char, not numbers"],
    ),
    "missing_column": (
        lambda d: _case(d, df=F.rename(columns={"p": "pressure"})),
        ["column 'p']: missing column 'p': a charge run needs pressure (p)",
         "map names under columns: in dataset.yaml"],
    ),
    "missing_column_mapped": (
        lambda d: _case(d, columns={"p": "P_kPa"}, units={"pressure": "kPa"},
                        df=F.rename(columns={"p": "P_kpa"})),
        ["missing column 'P_kPa' (mapped from 'p' under columns:)", "(did you mean 'P_kpa'?)"],
    ),
    "duplicate_csv_column": (
        lambda d: _case(d) or (d / "charge1.csv").write_text("t,p,p\n0,0,0\n0.001,0,0\n"),
        ["column 'p']: column 'p' appears more than once"],
    ),
    "pulse_missing_valve": (
        lambda d: _case(d, runs=[{**CHARGE, "kind": "pulse"}], df=F.drop(columns="valve")),
        ["missing column 'valve': a pulse run needs valve command (valve)"],
    ),
    "staircase_missing_u": (
        lambda d: _case(d, runs=[STAIR], df=F),
        ["missing column 'u': a staircase run needs input fraction u (u)"],
    ),
    "staircase_u_left_out": (
        lambda d: _case(d, runs=[STAIR], df=F, columns={"u": None}),
        ["[run 'stair1']: columns: leaves out u (null), but a staircase run needs input "
         "fraction u (u)", "kind: pulse"],
    ),
    "non_numeric": (
        lambda d: _case(d, df=_with(F, "p", 5, "abc")),
        ["[run 'charge1', column 'p', row 5 (line 6)]: non-numeric value; expected a number"],
    ),
    "nan_inf": (
        lambda d: _case(d, df=_with(_with(F, "p", 3, "NaN"), "t", 7, "inf")),
        ["column 'p', row 3 (line 4)]: missing value (empty cell or NaN)",
         "column 't', row 7 (line 8)]: infinite value (inf)"],
    ),
    "empty_cells": (
        lambda d: _case(d, df=_with(_with(F, "valve", 4, ""), "valve", 9, "")),
        ["column 'valve', row 4 (line 5)]: missing value (empty cell or NaN)",
         "(2 rows in all: 4, 9)"],
    ),
    "time_backwards": (
        lambda d: _case(d, df=_with(F, "t", 10, 0.002)),
        ["column 't', row 10 (line 11)]: time goes backwards: t = 0.002 s after 0.008 s"],
    ),
    "time_duplicated": (
        lambda d: _case(d, df=_with(F, "t", 8, 0.006)),
        ["column 't', row 8 (line 9)]: duplicated time stamp t = 0.006 s"],
    ),
    "valve_not_binary": (
        lambda d: _case(d, df=_with(F, "valve", 4, 2)),
        ["column 'valve', row 4 (line 5)]: valve = 2; expected the command 0 or 1"],
    ),
    "u_out_of_range": (
        lambda d: _case(d, runs=[STAIR], df=_with(FU, "u", 12, 1.5)),
        ["column 'u', row 12 (line 13)]: u = 1.5 is outside [0, 1]"],
    ),
    "pressure_looks_kpa": (
        lambda d: _case(d, df=F.assign(p=F["p"] * 100)),
        ["is outside the plausible gauge range -1.1 to 20 bar",
         "the values look like kPa (0 to 0.2529 bar); or psi", "set units: {pressure: kPa}"],
    ),
    "pressure_looks_mbar": (
        lambda d: _case(d, units={"pressure": "kPa"}, df=F.assign(p=F["p"] * 10_000)),
        ["the values look like mbar"],
    ),
    "yaml_alias_bomb": (
        lambda d: _raw(
            d,
            "name: yaml_alias_bomb\na0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n"
            + "".join(
                f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]\n" for i in range(1, 10)
            )
            + "runs: *a9\n",
        ),
        ["too complex to be a dataset description", "once its aliases are expanded"],
    ),
    "yaml_too_deep": (
        lambda d: _raw(d, "name: yaml_too_deep\nruns: " + "[" * 5000 + "]" * 5000 + "\n"),
        ["too complex to be a dataset description", "nested more than 20 levels deep"],
    ),
    "many_problems": (
        _multi,
        ["unknown key 'orign' (did you mean 'origin'?)",
         "unknown kind 'sin'",
         "charge1.csv [run 'charge1', column 'p', row 5 (line 6)]: non-numeric value",
         "pulse1.csv [run 'pulse1', column 't', row 10 (line 11)]: time goes backwards",
         "pulse1.csv [run 'pulse1', column 'valve', row 4 (line 5)]: valve = 3"],
    ),
}

BAD.update({
    "european_no_options": (
        lambda d: _eu_case(d, None),
        ["it looks `;`-separated with `,` as decimal mark: `csv: {sep: ';', decimal: ','}`",
         "the file is not UTF-8 (the bytes fit cp1252): `csv: {encoding: cp1252}`",
         "it has its header on line 4: `csv: {skip_rows: 3}`",
         "it has units on line 5 (s, bar, -, °C): `csv: {units_row: true}`",
         "add `csv: {encoding: cp1252, sep: ';', decimal: ',', skip_rows: 3, units_row: true}` "
         "to the run or the dataset"],
    ),
    "european_no_encoding": (
        lambda d: _eu_case(d, {k: v for k, v in EU_CSV.items() if k != "encoding"}),
        ["line 4 (the header) is not UTF-8 text (byte 0xd6)",
         "the file is not UTF-8 (the bytes fit cp1252): `csv: {encoding: cp1252}`"],
    ),
    "preamble_no_skip_rows": (
        _preamble,
        ["missing column 't'", "the file has its header on line 3: `csv: {skip_rows: 2}`"],
    ),
    "units_row_missing": (
        lambda d: _preamble(d, units_row=True),
        ["row 1 (line 2)]: non-numeric value",
         "has units on line 2 (s, bar, -): `csv: {units_row: true}`"],
    ),
    "bad_csv_options": (
        lambda d: _case(d, runs=[{**CHARGE, "csv": {"decimal": ",", "sep": ","}}],
                        csv={"sep": "::", "decimal": ";", "encoding": "utf-9", "skip_rows": -1,
                             "comment": "", "units_row": "yes", "delim": ","}),
        ["csv.sep: sep '::' is not one character, '\\t' or whitespace",
         "csv.decimal: decimal ';' is not '.' or ','",
         "csv.encoding: unknown encoding 'utf-9'",
         "csv.skip_rows: skip_rows -1 is not an integer >= 0",
         "csv.comment: comment '' is not a non-empty prefix",
         "csv.units_row: units_row 'yes' is not true or false",
         "csv.delim: unknown key 'delim'",
         "runs[0].csv.decimal [run 'charge1']: decimal ',' needs a sep other than ','"],
    ),
    "bad_run_columns_units": (
        lambda d: _case(d, runs=[{**CHARGE, "columns": {"valv": "V"},
                                  "units": {"time": "sec"}}]),
        ["runs[0].columns.valv [run 'charge1']: unknown canonical column 'valv'",
         "runs[0].units.time [run 'charge1']: time unit 'sec' is not one of s, ms"],
    ),
})

GOOD: dict[str, Callable[[Path], None]] = {
    "spa_good": _good,
    "european_csv": _european,
    "commented_tsv": _commented_tsv,
    "whitespace_txt": _whitespace_txt,
    "per_run_units": _per_run,
    "spa_good_bench": _good_bench,
}


def build(root: Path = HERE) -> None:
    """Recreate ``root/good`` and ``root/bad`` from the definitions above."""
    for sub in ("good", "bad"):
        shutil.rmtree(root / sub, ignore_errors=True)
    for name, make in GOOD.items():
        folder = root / "good" / name
        folder.mkdir(parents=True)
        make(folder)
    for name, (make, expected) in BAD.items():
        folder = root / "bad" / name
        folder.mkdir(parents=True)
        make(folder)
        (folder / "expected.txt").write_text("\n".join(expected) + "\n")


if __name__ == "__main__":
    build()
