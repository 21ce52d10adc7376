"""Coarse logs without time stamps: a serial-monitor session of five charge and five
discharge repeats, 50 pressure samples each at 20 ms in psi, through ``spa init``,
``spa validate`` and ``spa ingest`` (the identification is tested elsewhere)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from spa.cli import main
from spa.datasets import read_run_table
from spa.datasets.contract import PRESSURE_UNITS
from spa.datasets.yaml_loader import _UniqueKeyLoader
from spa.model.params import ValveParams
from spa.model.plant import simulate

VALVE = ValveParams(c1=0.084, k2=0.88, tau2=0.092, t_on=0.012, t_off=0.018)
DT = 1e-4  # the plant's step, s
STEP = 0.02  # the log's step, s (50 Hz)
SAMPLES = 50
REPEATS = 5
NOISE = 0.004  # bar


def _response(charge: bool, rng: np.random.Generator) -> np.ndarray:
    """50 samples of a charge (valve opened at t = 0 from 0 bar) or a discharge (closed at
    t = 0 from the plateau), logged every 20 ms, with sensor noise, in psi to 0.01."""
    n = round(SAMPLES * STEP / DT)
    command = np.zeros(n, dtype=np.int8)
    if charge:
        command[1:] = 1
    p = simulate(command, DT, VALVE, p0=0.0 if charge else VALVE.k2)
    logged = p[:: round(STEP / DT)][:SAMPLES] + rng.normal(0.0, NOISE, SAMPLES)
    return np.round(logged / PRESSURE_UNITS["psi"], 2)


def _session(folder: Path, stamped: bool) -> dict[str, np.ndarray]:
    """Write inflate_N.txt and deflate_N.txt (N = 1..5); return each run id's psi values."""
    folder.mkdir(parents=True)
    rng = np.random.default_rng(46)
    written = {}
    for i in range(1, REPEATS + 1):
        for stem, charge in (("inflate", True), ("deflate", False)):
            psi = _response(charge, rng)
            if stamped:
                ms = np.arange(SAMPLES) * round(STEP * 1e3)
                lines = [
                    "time_ms,pressure_psi",
                    *(f"{t},{p:.2f}" for t, p in zip(ms, psi, strict=True)),
                ]
            else:
                lines = ["pressure_psi", *(f"{p:.2f}" for p in psi)]
            (folder / f"{stem}_{i}.txt").write_text("\n".join(lines) + "\n")
            written[f"{stem}_{i}"] = psi
    return written


def _kinds(doc: dict) -> dict[str, str]:
    return {r["id"]: r["kind"] for r in doc["runs"]}


def _expected_kinds() -> dict[str, str]:
    return {
        f"{stem}_{i}": kind
        for i in range(1, REPEATS + 1)
        for stem, kind in (("inflate", "charge"), ("deflate", "discharge"))
    }


def _ingest(folder: Path, out: Path, capsys) -> str:
    """Validate and ingest ``folder``; return what validate printed."""
    capsys.readouterr()
    assert main(["validate", str(folder)]) == 0, capsys.readouterr().out
    said = capsys.readouterr().out
    assert main(["ingest", str(folder), str(out)]) == 0, capsys.readouterr().out
    return said


def test_init_validate_unstamped(tmp_path: Path, capsys) -> None:
    folder = tmp_path / "raw" / "serial"
    psi = _session(folder, stamped=False)
    assert main(["init", str(folder)]) == 0
    said = capsys.readouterr().out
    assert "drafted 10 run(s), 1 TODO(s)" in said
    text = (folder / "dataset.yaml").read_text()
    todo = "sample_step: TODO"
    # only the step to confirm (comment lines, such as the optional session day, aside)
    todos = [x for x in text.splitlines() if "TODO" in x and not x.startswith("#")]
    assert [x.split("  #")[0] for x in todos] == [todo], text
    doc = yaml.load(text.replace(todo, "sample_step: 0.0"), Loader=_UniqueKeyLoader)
    assert doc["columns"]["t"] is None
    assert doc["units"] == {"pressure": "psi"}
    assert _kinds(doc) == _expected_kinds()
    assert "valve_edges" not in text  # no valve column: nothing to say about its edges

    (folder / "dataset.yaml").write_text(text.replace(todo, f"sample_step: {STEP}"))
    said = _ingest(folder, tmp_path / "results" / "runs", capsys)
    assert said.count("at 50 Hz (t = row index * sample_step 0.02 s)") == 2 * REPEATS
    for rid, values in psi.items():
        table, meta = read_run_table(tmp_path / "results" / "runs" / f"{rid}.parquet")
        assert table["t"].tolist() == (np.arange(SAMPLES) * STEP).tolist()
        np.testing.assert_allclose(table["p"], values * PRESSURE_UNITS["psi"], rtol=1e-12)
        assert meta["sample_step"] == STEP
        assert meta["kind"] == _expected_kinds()[rid]
        assert "valve_edges" not in meta


def test_init_reads_ms_from_the_time_column_name(tmp_path: Path, capsys) -> None:
    folder = tmp_path / "raw" / "stamped"
    psi = _session(folder, stamped=True)
    assert main(["init", str(folder)]) == 0
    assert "drafted 10 run(s), 0 TODO(s)" in capsys.readouterr().out
    text = (folder / "dataset.yaml").read_text()
    doc = yaml.load(text, Loader=_UniqueKeyLoader)
    assert doc["units"] == {"time": "ms", "pressure": "psi"}
    assert "named 'time_ms'" in text
    assert doc["columns"]["t"] == "time_ms"
    assert "sample_step" not in doc
    assert _kinds(doc) == _expected_kinds()
    said = _ingest(folder, tmp_path / "results" / "runs", capsys)
    assert said.count("at 50 Hz, ") == 2 * REPEATS and "row index" not in said
    table, meta = read_run_table(tmp_path / "results" / "runs" / "deflate_3.parquet")
    np.testing.assert_allclose(table["t"], np.arange(SAMPLES) * STEP, rtol=0, atol=1e-12)
    np.testing.assert_allclose(table["p"], psi["deflate_3"] * PRESSURE_UNITS["psi"], rtol=1e-12)
    assert "sample_step" not in meta  # the time column gave the time


@pytest.mark.parametrize("declared, ok", [(0.0201, True), (0.025, False)])
def test_a_time_column_and_sample_step_must_agree(
    tmp_path: Path, capsys, declared: float, ok: bool
) -> None:
    folder = tmp_path / "raw" / "stamped"
    _session(folder, stamped=True)
    assert main(["init", str(folder)]) == 0
    text = (folder / "dataset.yaml").read_text()
    declare = text.replace("runs:\n", f"sample_step: {declared}\nruns:\n")
    (folder / "dataset.yaml").write_text(declare)
    capsys.readouterr()
    assert main(["validate", str(folder)]) == (0 if ok else 1)
    said = capsys.readouterr().out
    if not ok:
        line = next(x for x in said.splitlines() if "sample_step" in x)
        assert "run 'deflate_1'" in line and "column 'time_ms'" in line
        assert "0.02 s" in line and "0.025 s" in line


def test_physical_plant_logged_at_20_hz_without_header(tmp_path: Path, capsys) -> None:
    """Five charge and five discharge repeats of the physical plant (not the model), logged
    at 20 Hz in kPa as headerless one-column .log files: init leaves only the step."""
    from spa.synthetic._physical_core import PhysicalPlant
    from spa.synthetic.physical import simulate_physical

    plant, dt, fs, n = PhysicalPlant(), 1e-3, 20.0, 2000
    folder = tmp_path / "raw" / "arduino"
    folder.mkdir(parents=True)
    rng = np.random.default_rng(8)
    logged = {}
    for i in range(1, REPEATS + 1):
        charge = np.ones(n, dtype=np.int8)
        charge[0] = 0
        up = simulate_physical(plant, charge, dt, fs=fs, rng=rng)["p"].to_numpy()
        down = simulate_physical(plant, 1 - charge, dt, fs=fs, p0=float(up[-1]), rng=rng)
        for stem, p in (("fill", up), ("vent", down["p"].to_numpy())):
            kpa = np.round(p * 100.0, 1)
            (folder / f"{stem}{i}.log").write_text("".join(f"{x:.1f}\n" for x in kpa))
            logged[f"{stem}{i}"] = kpa
    assert main(["init", str(folder)]) == 0
    assert "drafted 10 run(s), 1 TODO(s)" in capsys.readouterr().out
    text = (folder / "dataset.yaml").read_text()
    doc = yaml.load(text.replace("sample_step: TODO", "sample_step: 0.0"), Loader=_UniqueKeyLoader)
    assert doc["columns"] == {"t": None, "p": "col1"} and doc["units"] == {"pressure": "kPa"}
    pairs = (("fill", "charge"), ("vent", "discharge"))
    assert _kinds(doc) == {f"{s}{i}": k for i in range(1, REPEATS + 1) for s, k in pairs}
    step = 1 / fs
    (folder / "dataset.yaml").write_text(text.replace("sample_step: TODO", f"sample_step: {step}"))
    _ingest(folder, tmp_path / "results" / "runs", capsys)
    table, meta = read_run_table(tmp_path / "results" / "runs" / "vent4.parquet")
    assert table["t"].tolist() == (np.arange(len(logged["vent4"])) * step).tolist()
    np.testing.assert_allclose(table["p"], logged["vent4"] / 100.0, rtol=1e-12)
    assert meta["sample_step"] == step
