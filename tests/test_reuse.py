"""spa.pipeline.reuse: a stage is reused exactly when nothing it reads, no setting it sees and
none of its code changed; never a stale result."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from spa.pipeline import reuse, store
from spa.pipeline.jobs import (
    Names,
    joined_outputs,
    read_files,
    read_stages,
    stage_job,
    stage_params,
)
from spa.pipeline.outputs import stage_outputs
from spa.pipeline.reuse import Store, file_digest, run_or_reuse, stage_digest

ROOT = Path(__file__).resolve().parents[1]
STAGES = {"identify": "identify", "tune": "tune", "sine": "sine", "closed_loop": "closed_loop"}


def analysis_job(tmp_path: Path, **params: object) -> SimpleNamespace:
    """A shared job of four real stages over files under tmp_path, as analyse.smk builds it."""
    res = tmp_path / "res"
    outputs = joined_outputs(STAGES, lambda s: stage_outputs(s, str(res), "d1"))
    runs = res / "d1" / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    (runs / "r1.parquet").write_bytes(b"run one")
    status = res / "d1" / "status" / "runs.json"
    status.parent.mkdir(parents=True, exist_ok=True)
    status.write_text('{"stage": "runs", "ok": true}\n')
    base = {
        "code": "abc",
        "stages": STAGES,
        "cfg": {"identify": {"n_boot": 50}, "tune": {"score": "J"}, "sine": {"settle": 2}},
        "tuning": {"score": "J"},
        "seed": 1,
        "nominal": {"k2": 3.0},
        "selected": ["pwm"],
    }
    return SimpleNamespace(
        input=Names({"runs": str(runs), "status": str(status)}),
        output=Names(outputs),
        log=Names({s: str(res / "logs" / "d1" / f"{s}.log") for s in STAGES}),
        params=Names({**base, **params}),
        wildcards=Names({"dataset": "d1"}),
    )


def fake_script(tmp_path: Path, text: str = "v1") -> Path:
    script = tmp_path / "scripts" / "stage.py"
    script.parent.mkdir(parents=True, exist_ok=True)
    script.write_text(f"# {text}\n")
    return script


def fill(view: SimpleNamespace, stage: str, calls: list[str], salt: str = "") -> None:
    """A stage's work: every output from what it reads (its inputs' bytes, its settings)."""
    calls.append(stage)
    seen = json.dumps(dict(view.params.items()), sort_keys=True, default=str)
    text = (
        seen
        + salt
        + "".join(
            Path(p).read_text(errors="replace")
            for k, p in sorted(view.input.items())
            if Path(p).is_file() and k != "status"
        )
    )
    for key, path in view.output.items():
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        if key == "status":
            out.write_text(json.dumps({"stage": stage, "dataset": "d1", "ok": True}) + "\n")
        elif key == "figures":
            out.mkdir(parents=True, exist_ok=True)
            (out / "a.png").write_text(text)
        elif key == "recommendation":  # what it chose, and an echo of its settings
            chosen = view.params.cfg.get("chosen", text)
            record = {"recommended": {"setting": chosen, "J": 1.0}, "echo": text}
            out.write_text(json.dumps(record))
        else:
            out.write_text(f"{key}: {text}")
    Path(view.log[0]).parent.mkdir(parents=True, exist_ok=True)
    Path(view.log[0]).write_text(f"{stage} ran\n")


def run_job(job: SimpleNamespace, script: Path, calls: list[str], salt: str = "",
            enabled: bool = True, delete: bool = True) -> dict[str, str]:  # fmt: skip
    """The job as run_job.py runs it, after Snakemake deleted every declared output."""
    if delete:
        for path in job.output:
            p = Path(path)
            if p.is_dir():
                shutil.rmtree(p)
            elif p.exists():
                p.unlink()
    results = Path(job.input.runs).parents[1]
    how = {}
    for stage in STAGES:
        view = stage_job(job, stage)
        how[stage] = run_or_reuse(
            view, stage, script, lambda v=view, s=stage: fill(v, s, calls, salt),
            results=results, reads=read_files(job, stage), enabled=enabled,
        )  # fmt: skip
    return how


def snapshot(job: SimpleNamespace) -> dict[str, bytes]:
    out = {}
    for key, path in job.output.items():
        p = Path(path)
        if key.endswith("status"):
            record = json.loads(p.read_text())
            record.pop("reuse")
            out[key] = json.dumps(record).encode()
        elif p.is_dir():
            out.update({f"{key}/{q.name}": q.read_bytes() for q in sorted(p.iterdir())})
        else:
            out[key] = p.read_bytes()
    return out


def test_an_unchanged_job_is_restored_byte_for_byte_and_says_so(tmp_path) -> None:
    job, script, calls = analysis_job(tmp_path), fake_script(tmp_path), []
    assert set(run_job(job, script, calls).values()) == {"computed"}
    first = snapshot(job)
    calls.clear()
    assert set(run_job(job, script, calls).values()) == {"reused"}
    assert calls == [] and snapshot(job) == first
    status = json.loads(Path(job.output.identify__status).read_text())
    assert status["reuse"] == "reused"
    assert "reused: identify" in Path(job.log.identify).read_text()
    assert (Path(job.input.runs).parents[1] / ".store" / "identify").is_dir()


def test_a_tuning_change_reruns_tune_and_what_reads_it_only(tmp_path) -> None:
    script, calls = fake_script(tmp_path), []
    job = analysis_job(tmp_path)
    run_job(job, script, calls)
    params = Path(job.output.identify__params).read_bytes()
    calls.clear()
    changed = analysis_job(tmp_path, tuning={"score": "J_exact"})
    how = run_job(changed, script, calls)
    assert how == {"identify": "reused", "tune": "computed", "sine": "reused",
                   "closed_loop": "computed"}  # fmt: skip
    assert calls == ["tune", "closed_loop"]
    assert Path(job.output.identify__params).read_bytes() == params


def test_the_closed_loop_reads_the_recommended_setting_alone(tmp_path) -> None:
    """A tuning change that leaves the recommended setting (and the adequacy) as it was
    leaves the closed loop reused, though the recommendation's other fields changed; a
    change of the setting, or of the adequacy, recomputes it; the closed loop sees those
    fields alone."""

    def chosen(setting: str, **params: object) -> SimpleNamespace:
        cfg = {"identify": {"n_boot": 50}, "tune": {"chosen": setting}, "sine": {}}
        return analysis_job(tmp_path, cfg=cfg, **params)

    script, calls = fake_script(tmp_path), []
    run_job(chosen("pwm 20 Hz"), script, calls)
    calls.clear()
    job = chosen("pwm 20 Hz", tuning={"score": "J_exact"})
    how = run_job(job, script, calls)
    assert how["tune"] == "computed" and how["closed_loop"] == "reused"
    assert "J_exact" in json.loads(Path(job.output.tune__recommendation).read_text())["echo"]
    seen = stage_job(job, "closed_loop").input.recommendation
    assert yaml.safe_load(Path(seen).read_text()) == {"recommended": {"setting": "pwm 20 Hz"}}
    calls.clear()
    how = run_job(chosen("dsm 20 ms"), script, calls)
    assert how["closed_loop"] == "computed" and "closed_loop" in calls
    # the adequacy: another view, another digest
    before = read_files(job, "closed_loop")["tune__recommendation"]
    rec = Path(job.output.tune__recommendation)
    rec.write_text(json.dumps({**json.loads(rec.read_text()), "adequacy": {"adequate": False}}))
    after = read_files(job, "closed_loop")["tune__recommendation"]
    assert before != after and file_digest(before) != file_digest(after)


def test_project_keeps_the_named_fields_alone() -> None:
    record = {"recommended": {"setting": {"type": "pwm"}, "J": 2.0}, "adequacy": None, "x": 1}
    part = store.project(record, ("recommended.setting", "adequacy", "missing.field"))
    assert part == {"recommended": {"setting": {"type": "pwm"}}, "adequacy": None}


def test_a_stage_whose_input_came_back_the_same_bytes_is_reused(tmp_path) -> None:
    """Content, not order: a recomputed tune that writes what it wrote before leaves
    closed_loop reused."""
    script, calls = fake_script(tmp_path), []
    job = analysis_job(tmp_path)
    run_job(job, script, calls)
    shutil.rmtree(Path(job.input.runs).parents[1] / ".store" / "tune")
    calls.clear()
    how = run_job(job, script, calls)
    assert how["tune"] == "computed" and how["closed_loop"] == "reused"


@pytest.mark.parametrize("change", ["input", "setting", "script", "package", "library", "output"])
def test_a_change_anywhere_a_stage_looks_is_never_served_stale(tmp_path, monkeypatch, change):
    script, calls = fake_script(tmp_path), []
    job = analysis_job(tmp_path)
    run_job(job, script, calls)
    old = snapshot(job)
    calls.clear()
    salt = ""
    if change == "input":
        (Path(job.input.runs) / "r1.parquet").write_bytes(b"run one, edited")
        salt = "edited"
    elif change == "setting":
        job = analysis_job(tmp_path, cfg={"identify": {"n_boot": 51}, "tune": {}, "sine": {}})
        salt = "setting"
    elif change == "script":
        script = fake_script(tmp_path, "v2")
        salt = "script"
    elif change == "package":  # an edit anywhere in spa/
        monkeypatch.setattr("spa.io.package_digest", lambda: "edited")
        salt = "package"
    elif change == "library":
        monkeypatch.setattr(reuse, "LIBRARIES", (*reuse.LIBRARIES, "pytest"))
        salt = "library"
    elif change == "output":  # the outputs' paths, as when a dataset's figures are left out
        out = dict(job.output.items())
        out["sine__fig8"] = out["sine__fig8"].replace("fig8", "fig8b")
        job.output = Names(out)
        salt = "output"
    how = run_job(job, script, calls, salt=salt)
    first = "identify" if change != "output" else "sine"
    assert how[first] == "computed"
    if change != "output":
        assert set(how.values()) == {"computed"}  # and so is every stage after it
        assert all(v != old.get(k) for k, v in snapshot(job).items() if not k.endswith("status"))


def test_a_damaged_store_entry_is_recomputed_not_served(tmp_path) -> None:
    """A stored file changed in place (through a hard link to an output, or by hand) fails
    its checksum: the entry is dropped and the stage runs."""
    script, calls = fake_script(tmp_path), []
    job = analysis_job(tmp_path)
    run_job(job, script, calls)
    good = snapshot(job)
    store = Path(job.input.runs).parents[1] / ".store" / "sine"
    (stored,) = [p for p in store.rglob("files/table")]
    stored.unlink()
    stored.write_text("tampered")
    calls.clear()
    how = run_job(job, script, calls)
    assert how["sine"] == "computed" and calls == ["sine"] and snapshot(job) == good


def test_reuse_off_recomputes_everything_to_the_same_bytes(tmp_path) -> None:
    script, calls = fake_script(tmp_path), []
    job = analysis_job(tmp_path)
    run_job(job, script, calls)
    first = snapshot(job)
    calls.clear()
    assert set(run_job(job, script, calls, enabled=False).values()) == {"computed"}
    assert calls == list(STAGES) and snapshot(job) == first


def test_a_stage_sees_only_the_settings_and_inputs_its_digest_covers(tmp_path) -> None:
    job = analysis_job(tmp_path)
    tune = stage_job(job, "tune")
    assert set(dict(tune.params.items())) == {"cfg", "code", "stages", "tuning", "selected"}
    assert tune.params.cfg == {"score": "J"}
    assert set(stage_params(job, "identify")) == {"cfg", "code", "stages", "seed", "nominal"}
    assert set(dict(stage_job(job, "sine").params.items())) == {"cfg", "code", "stages"}
    # sine reads the run tables and identify's outputs, not tune's
    assert stage_job(job, "sine").input.get("recommendation") is None
    assert stage_job(job, "closed_loop").input.recommendation == job.output.tune__recommendation
    assert read_stages("closed_loop", STAGES) == ["identify", "tune"]
    assert not any(k.startswith("tune__") for k in read_files(job, "sine"))


def test_the_digest_ignores_how_a_status_came_not_what_it_says(tmp_path) -> None:
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"stage": "x", "ok": True, "reuse": "reused"}))
    b.write_text(json.dumps({"stage": "x", "ok": True, "reuse": "computed"}))
    assert file_digest(a, True) == file_digest(b, True)
    assert file_digest(a) != file_digest(b)
    b.write_text(json.dumps({"stage": "x", "ok": False, "reuse": "reused"}))
    assert file_digest(a, True) != file_digest(b, True)


def test_an_incomplete_store_entry_is_not_an_entry(tmp_path) -> None:
    store = Store(tmp_path / ".store")
    out = tmp_path / "out.csv"
    out.write_text("x")
    assert store.save("sine", "d" * 64, {"table": str(out)}, None)
    assert not store.restore("sine", "d" * 64, {"table": str(out), "other": "y"}, None)
    assert not store.save("sine", "e" * 64, {"table": str(tmp_path / "missing.csv")}, None)
    assert not (tmp_path / ".store" / "sine" / ("e" * 64)).exists()
    (tmp_path / ".store" / "sine" / ("d" * 64) / "manifest.json").write_text("{")
    assert not store.restore("sine", "d" * 64, {"table": str(out)}, None)


def test_digest_is_relative_to_the_results_folder(tmp_path) -> None:
    job = analysis_job(tmp_path)
    view = stage_job(job, "sine")
    res = Path(job.input.runs).parents[1]
    one = stage_digest(view, "sine", "c", read_files(job, "sine"), results=res)
    assert one == stage_digest(view, "sine", "c", read_files(job, "sine"), results=res)
    assert one != stage_digest(view, "sine", "c2", read_files(job, "sine"), results=res)


# The pipeline: a tuning change and a forced recompute, the small config, the simulated
# dataset alone (about three minutes of CPU).
def _snakemake(cfg: Path, results: Path, *extra: str, reuse: bool = True) -> None:
    cmd = [sys.executable, "-m", "snakemake", "reproduce-all", "-c2", "--configfile",
           "config/small.yaml", str(cfg), *extra, "--config", f"results={results}",
           f"reuse={reuse}"]  # fmt: skip
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]


def _tables(results: Path) -> dict[str, bytes]:
    return {
        p.relative_to(results).as_posix(): p.read_bytes()
        for p in sorted(results.rglob("*"))
        if p.is_file() and p.suffix in (".csv", ".yaml", ".parquet", ".h", ".ino", ".html")
        and ".store" not in p.parts and "logs" not in p.parts and "provenance" not in p.parts
        and p.name != "status.yaml"
    }  # fmt: skip


def test_a_tuning_change_reuses_identification_and_a_recompute_gives_the_same_tables(tmp_path):
    raw = tmp_path / "raw"
    raw.mkdir()
    cfg = tmp_path / "only_sim.yaml"
    cfg.write_text(f"datasets:\n  raw_dir: {raw}\n  include: []\n  exclude: []\n")
    results = tmp_path / "res"
    _snakemake(cfg, results)
    ident = {p.name: p.read_bytes() for p in (results / "sim" / "identification").iterdir()}
    tuned = tmp_path / "tuned.yaml"
    tuned.write_text(
        cfg.read_text() + "tuning:\n  max_chattering: 0.04\nlinearity:\n  sine:\n    settle: 2.5\n"
    )
    _snakemake(tuned, results)
    status = (results / "status.yaml").read_text()
    import yaml

    how = yaml.safe_load(status)["stages"]["sim"]
    assert how["identify"] == how["validate_model"] == how["staircase"] == "reused"
    assert how["chirp"] == "reused"
    assert how["tune"] == how["sine"] == how["page"] == "computed"
    # the recommended setting did not move: the closed loop is restored, and the tuning's
    # corners, its predicted staircases and its figures came from the memo
    assert how["closed_loop"] == "reused"
    assert any((results / ".store" / "memo" / "tuning-corners").iterdir())
    assert {p.name: p.read_bytes() for p in (results / "sim" / "identification").iterdir()} == ident
    reused = _tables(results)
    _snakemake(tuned, results, "--forceall", reuse=False)
    status = yaml.safe_load((results / "status.yaml").read_text())["stages"]["sim"]
    assert set(status.values()) == {"computed"}
    assert _tables(results) == reused


@pytest.mark.parametrize("store_on", [False, True])
def test_a_job_collects_garbage_less_often_and_gives_the_thresholds_back(
    tmp_path, store_on
) -> None:
    """Every stage runs under JOB_GC_THRESHOLD; after the job, and after a stage that fails,
    the caller's thresholds are back (a notebook or pytest calling run_job keeps its own)."""
    import gc

    seen = tmp_path / "thresholds.txt"
    scripts = tmp_path / "scripts"
    scripts.mkdir()
    for stage in STAGES:
        (scripts / f"{stage}.py").write_text(
            "import gc\n"
            f"with open({str(seen)!r}, 'a') as f:\n"
            "    f.write(repr(gc.get_threshold()) + '\\n')\n"
            "from pathlib import Path\n"
            "for p in snakemake.output:\n"
            "    Path(p).parent.mkdir(parents=True, exist_ok=True)\n"
            "    Path(p).mkdir() if not Path(p).suffix else Path(p).write_text('x')\n"
        )
    job = analysis_job(tmp_path, store=store_on)
    job.config = {"reuse": True}
    before = gc.get_threshold()
    try:
        gc.set_threshold(700, 10, 10)
        reuse.run_job(job, scripts)
        assert gc.get_threshold() == (700, 10, 10)
        lines = seen.read_text().splitlines()
        assert lines == [repr(reuse.JOB_GC_THRESHOLD)] * len(STAGES)

        (scripts / "tune.py").write_text("raise RuntimeError('a broken stage')\n")
        for path in job.output:  # as Snakemake before a rerun
            p = Path(path)
            shutil.rmtree(p) if p.is_dir() else p.unlink(missing_ok=True)
        with pytest.raises(RuntimeError, match="a broken stage"):
            reuse.run_job(job, scripts)
        assert gc.get_threshold() == (700, 10, 10)
    finally:
        gc.set_threshold(*before)
