"""One bench session in every format a bench writes, identified as its plain-CSV twin.

raw/example (ms, kPa; CSV, MATLAB v5, Parquet) is ingested; its canonical run tables are then
written again as a lab mixing loggers would: the charge as a European spreadsheet export,
the discharge as a LabVIEW ``.lvm`` with decimal commas, the pulse as a dSpace ControlDesk
recording, the IIPFM staircase as MATLAB v7.3 in psi, the PWM staircase as TDMS with waveform
timing and again as a commented TSV. That folder must validate, ingest to the values its files
hold, identify the same valve, and be drafted by ``spa init`` with every file named.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io
import yaml
from file_writers import dspace_recording, to_savemat, write_lvm, write_mat73, write_tdms

from spa.cli import main
from spa.datasets import ingest_dataset, read_run_table, validate_dataset
from spa.identification import identify_runs

ROOT = Path(__file__).resolve().parents[1]
PSI = 0.0689475729  # bar per psi, as spa.datasets.contract converts it


def _tables(folder: Path, out: Path) -> tuple[dict[str, pd.DataFrame], dict[str, str]]:
    ingest_dataset(folder, out)
    runs, kinds = {}, {}
    for path in sorted(out.glob("*.parquet")):
        table, meta = read_run_table(path)
        runs[meta["run"]], kinds[meta["run"]] = table, meta["kind"]
    return runs, kinds


def _numbers(values: np.ndarray, decimal: str = ".") -> list[str]:
    text = [repr(float(v)) for v in values]
    return [v.replace(".", decimal) for v in text] if decimal != "." else text


def _european(path: Path, df: pd.DataFrame) -> None:
    rows = zip(*(_numbers(df[c].to_numpy(), ",") for c in ("t", "p", "valve")), strict=True)
    lines = ["Prüfstand: Ventil 3/2", "Datum: 23.11.2026", "Raum: 21 °C"]
    lines += ["Zeit;Druck;Ventil", "s;bar;-", *(";".join(r) for r in rows)]
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode("cp1252"))


def _tsv(path: Path, df: pd.DataFrame) -> None:
    rows = zip(*(_numbers(df[c].to_numpy()) for c in ("t", "p", "valve", "u")), strict=True)
    lines = ["# logger v2.1, 1 kHz", "t\tp\tvalve\tu", *("\t".join(r) for r in rows), "# end"]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("session")
    plain = base / "example"
    shutil.copytree(ROOT / "raw" / "example", plain)
    runs, _ = _tables(plain, base / "plain_runs")
    mixed = base / "mixed"
    mixed.mkdir()
    pwm = runs["staircase_pwm-20Hz"]
    _european(mixed / "charge.csv", runs["charge"])
    d = runs["discharge"]
    write_lvm(mixed / "discharge.lvm", [[{"X_Value": d["t"], "p": d["p"], "valve": d["valve"]}]])
    q = runs["pulse"]
    signals = {
        "Platform/Model Root/Sensors/p_act": q["p"],
        "Platform/Model Root/Out/valve": q["valve"],
    }
    rec = dspace_recording("time", q["t"].to_numpy(), signals)
    scipy.io.savemat(mixed / "pulse.mat", {"rec": to_savemat(rec)})
    s = runs["staircase_iipfm-20ms-G1.2"]
    write_mat73(
        mixed / "iipfm.mat",
        {"t": s["t"], "p_psi": s["p"] / PSI, "valve": s["valve"].astype(bool), "u": s["u"]},
    )
    step = float(np.median(np.diff(pwm["t"])))
    write_tdms(
        mixed / "pwm.tdms",
        "Measured",
        [{"p": pwm["p"], "valve": pwm["valve"], "u": pwm["u"]}],
        waveform=(float(pwm["t"].iloc[0]), step),
    )
    _tsv(mixed / "pwm.tsv", pwm)
    spec = yaml.safe_load((plain / "dataset.yaml").read_text())
    spec.update(name="mixed", units={"time": "s", "pressure": "bar"})
    spec["columns"] = {"t": "t", "p": "p", "valve": "valve", "u": "u"}
    by_id = {r["id"]: r for r in spec["runs"]}
    eu = {"sep": ";", "decimal": ",", "encoding": "cp1252", "skip_rows": 3, "units_row": True}
    spec["runs"] = [
        {**by_id["charge"], "file": "charge.csv", "csv": eu,
         "columns": {"t": "Zeit", "p": "Druck", "valve": "Ventil"}},
        {**by_id["discharge"], "file": "discharge.lvm", "columns": {"t": "X_Value"}},
        {**by_id["pulse"], "file": "pulse.mat", "columns": {"t": "time", "p": "p_act"}},
        {**by_id["staircase_iipfm-20ms-G1.2"], "file": "iipfm.mat",
         "columns": {"p": "p_psi"}, "units": {"pressure": "psi"}},
        {**by_id["staircase_pwm-20Hz"], "file": "pwm.tdms"},
        {**by_id["staircase_pwm-20Hz"], "id": "staircase_pwm-20Hz-tsv", "file": "pwm.tsv",
         "csv": {"comment": "#"}},
    ]  # fmt: skip
    (mixed / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False, allow_unicode=True))
    return {"base": base, "plain": plain, "mixed": mixed}


def test_the_session_validates_and_ingests_to_the_values_its_files_hold(session) -> None:
    problems = validate_dataset(session["mixed"])
    assert not [p for p in problems if p.is_error], "\n".join(map(str, problems))
    plain, _ = _tables(session["plain"], session["base"] / "p2")
    mixed, kinds = _tables(session["mixed"], session["base"] / "m2")
    twin = {rid: plain[rid.removesuffix("-tsv")] for rid in mixed}
    assert len(mixed) == 6
    for rid, table in mixed.items():
        want = twin[rid]
        assert list(table.columns) == list(want.columns), rid
        assert len(table) == len(want), rid
        # text, MATLAB and .lvm hold the very numbers; TDMS time is offset + i * increment
        # and v7.3 pressure went through psi: those agree to rounding
        exact = rid not in ("staircase_pwm-20Hz", "staircase_iipfm-20ms-G1.2")
        for col in table.columns:
            got, ref = table[col].to_numpy(np.float64), want[col].to_numpy(np.float64)
            if exact or col in ("valve", "u"):
                np.testing.assert_array_equal(got, ref, err_msg=f"{rid}.{col}")
            else:
                np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12, err_msg=f"{rid}.{col}")
    assert kinds["staircase_pwm-20Hz-tsv"] == "staircase"


def test_the_session_identifies_the_valve_of_its_plain_twin(session) -> None:
    plain, plain_kinds = _tables(session["plain"], session["base"] / "p3")
    mixed, mixed_kinds = _tables(session["mixed"], session["base"] / "m3")
    a = identify_runs(plain, plain_kinds).to_valve_params()
    b = identify_runs(mixed, mixed_kinds).to_valve_params()
    for name in ("c1", "k2", "tau2", "t_on", "t_off"):
        assert getattr(b, name) == pytest.approx(getattr(a, name), rel=1e-9), name


def test_spa_init_drafts_the_session_naming_every_file(session, tmp_path, capsys) -> None:
    folder = tmp_path / "mixed"
    shutil.copytree(session["mixed"], folder)
    (folder / "dataset.yaml").unlink()
    assert main(["init", str(folder)]) == 0
    draft = yaml.safe_load((folder / "dataset.yaml").read_text())
    files = {run["file"] for run in draft["runs"]}
    assert files == {"charge.csv", "discharge.lvm", "pulse.mat", "iipfm.mat", "pwm.tdms", "pwm.tsv"}
    text = (folder / "dataset.yaml").read_text()
    assert "sep: ;" in text.replace("'", "") and "decimal: ," in text.replace("'", "")


def test_the_european_file_without_its_options_is_refused_naming_sep_and_decimal(
    session, tmp_path
) -> None:
    folder = tmp_path / "mixed"
    shutil.copytree(session["mixed"], folder)
    spec = yaml.safe_load((folder / "dataset.yaml").read_text())
    del spec["runs"][0]["csv"]
    (folder / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False, allow_unicode=True))
    text = "\n".join(str(p) for p in validate_dataset(folder))
    assert "`;`-separated with `,` as decimal mark" in text, text
    assert "csv: {sep: ';', decimal: ','}" in text, text
