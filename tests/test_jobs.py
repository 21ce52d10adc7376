"""spa.pipeline.jobs: a shared job's view for each of its stages."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from spa.pipeline.jobs import Names, joined_outputs, stage_job
from spa.pipeline.outputs import stage_outputs


def shared_job(stages: list[str]) -> SimpleNamespace:
    outputs = joined_outputs(stages, lambda s: stage_outputs(s, "res", "d1"))
    return SimpleNamespace(
        input=Names({"runs": "res/d1/runs", "params": "res/d1/identification/params.yaml"}),
        output=Names(outputs),
        log=Names({s: f"res/logs/d1/{s}.log" for s in stages}),
        params=Names({"code": "abc", "stages": stages, "cfg": {"sine": {"settle": 2}}}),
        wildcards=Names({"dataset": "d1"}),
    )


def test_each_stage_sees_exactly_its_own_outputs_log_and_settings() -> None:
    stages = ["validate_model", "staircase", "sine", "chirp"]
    job = shared_job(stages)
    seen: set[str] = set()
    for stage in stages:
        view = stage_job(job, stage)
        own = stage_outputs(stage, "res", "d1")
        assert dict(view.output.items()) == own  # same keys and paths as a rule of its own
        assert view.output.status == f"res/d1/status/{stage}.json"
        assert view.log[0] == f"res/logs/d1/{stage}.log"
        assert view.params.code == "abc"
        assert view.params.cfg == ({"settle": 2} if stage == "sine" else {})
        assert view.wildcards.dataset == "d1" and view.input.runs == "res/d1/runs"
        assert not seen & set(own.values())  # no output shared between stages
        seen |= set(own.values())
    assert seen == set(job.output)


def test_a_stage_the_job_does_not_run_is_refused() -> None:
    with pytest.raises(KeyError, match="no outputs of stage 'tune'"):
        stage_job(shared_job(["sine"]), "tune")


def test_names_behaves_like_a_snakemake_namedlist() -> None:
    n = Names({"a": 1, "b": 2})
    assert (n.a, n["b"], n[0], len(n), list(n)) == (1, 2, 1, 2, [1, 2])
    with pytest.raises(AttributeError):
        _ = n.c


def test_a_failed_stage_skips_the_stages_that_read_it_and_no_other(tmp_path) -> None:
    """In a shared job the stages run in turn: a staircase failure must not skip sine (which
    reads runs and params only), while a failed identification skips both."""
    import logging

    from spa.pipeline.status import read_status, run_stage, write_status

    stages = ["staircase", "sine"]
    job = shared_job(stages)
    out = {k: str(tmp_path / v) for k, v in job.output.items()}
    job.output = Names(out)
    log = logging.getLogger("test_jobs")
    status_dir = tmp_path / "res" / "d1" / "status"
    status_dir.mkdir(parents=True)

    def boom() -> None:
        raise ValueError("no steps")

    ran = []
    assert not run_stage(stage_job(job, "staircase"), "staircase", boom, log)
    assert run_stage(stage_job(job, "sine"), "sine", lambda: ran.append("sine"), log)
    assert ran == ["sine"]
    assert read_status(status_dir / "sine.json")["ok"] is True
    write_status(status_dir / "identify.json", "identify", "d1", ["IdentificationError: x"])
    assert not run_stage(stage_job(job, "sine"), "sine", lambda: ran.append("again"), log)
    assert ran == ["sine"]
    assert read_status(status_dir / "sine.json")["upstream"] == "identify"


def test_an_exported_name_wins_over_a_submodule_of_the_same_name() -> None:
    """spa.identification exports the function identify from its submodule identify: once
    the submodule is imported, the package's name must still be the function."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import spa.identification.identify\n"
        "m = sys.modules['spa.identification.identify']\n"
        "from spa.identification import identify\n"
        "import spa.identification as pkg\n"
        "assert callable(identify) and identify is m.identify, identify\n"
        "assert pkg.identify is m.identify\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_an_earlier_stage_outputs_are_a_later_stage_inputs() -> None:
    """In the analyse job, tune reads the params identify wrote: input.params."""
    stages = {"identify": "identify", "tune": "tune", "sine": "sine"}
    job = shared_job(list(stages))
    job.input = Names({"runs": "res/d1/runs"})
    job.params = Names({"stages": stages, "cfg": {}})
    assert stage_job(job, "identify").input.get("params") is None  # nothing before it
    tune = stage_job(job, "tune")
    assert tune.input.params == "res/d1/identification/params.yaml"
    assert tune.input.runs == "res/d1/runs"
    # a key already taken keeps its first meaning: identify's status, not tune's
    assert stage_job(job, "sine").input.status == "res/d1/status/identify.json"


def test_figures_the_job_does_not_draw_are_removed_and_nothing_else(tmp_path) -> None:
    from spa.pipeline.jobs import remove_undrawn_figures

    res = tmp_path / "res"
    stages = {"identify": "identify", "validate_model": "validate_model"}
    every = {s: stage_outputs(s, res, "d1") for s in stages}
    for paths in every.values():
        for key, path in paths.items():
            target = Path(path)
            if key == "figures":
                (target / "charge.png").parent.mkdir(parents=True, exist_ok=True)
                (target / "charge.png").write_text("old")
            else:
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_text("old")
    kept = {s: stage_outputs(s, res, "d1", figures=False) for s in stages}
    job = SimpleNamespace(
        output=Names(joined_outputs(stages, lambda s: kept[s])),
        params=Names({"stages": stages}),
        wildcards=Names({"dataset": "d1"}),
    )
    removed = remove_undrawn_figures(job)
    gone = {p for s in stages for k, p in every[s].items() if k not in kept[s]}
    # 4 PNG (Fig. 2a-c and the laws), 4 SVG, the figures folder
    assert set(removed) == gone and len(gone) == 9
    assert not any(Path(p).exists() for p in gone)
    assert all(Path(p).read_text() == "old" for s in stages for p in kept[s].values())
    assert remove_undrawn_figures(job) == []  # nothing left to remove
    # a job that draws its figures removes nothing
    Path(every["identify"]["fig2a"]).write_text("new")
    job.output = Names(joined_outputs(stages, lambda s: every[s]))
    assert remove_undrawn_figures(job) == []
    assert Path(every["identify"]["fig2a"]).read_text() == "new"


@pytest.mark.parametrize(
    "error",
    [
        OSError(28, "No space left on device"),
        OSError(27, "File too large"),
        OSError(30, "Read-only file system"),
        MemoryError(),
    ],
)
def test_an_error_of_the_environment_fails_the_job_and_records_nothing(
    tmp_path, monkeypatch, error
) -> None:
    """A full disk, `ulimit -f`, a read-only results folder or exhausted memory is not the
    dataset's failure: no placeholder, no status, the job exits non-zero saying why."""
    import logging

    from spa import io
    from spa.pipeline.status import EnvironmentFailure, run_stage

    job = shared_job(["sine"])
    job.output = Names({k: str(tmp_path / v) for k, v in job.output.items()})

    monkeypatch.setattr(io, "write_csv", _raise(error))

    def work() -> None:  # a writer of the stage's table hitting the error
        io.write_csv(None, job.output.sine__table)

    with pytest.raises(EnvironmentFailure, match="stopped by its environment, not by its data"):
        run_stage(stage_job(job, "sine"), "sine", work, logging.getLogger("test_jobs"))
    assert not any(tmp_path.rglob("*.*")), "a placeholder or status was written"


def test_a_refused_recording_is_the_data_and_a_refused_output_the_environment(tmp_path) -> None:
    from spa.pipeline.status import environment_error

    denied = PermissionError(13, "Permission denied")
    denied.filename = str(tmp_path / "raw" / "d" / "a.csv")
    assert environment_error(denied, own=tmp_path / "results") is None
    denied.filename = str(tmp_path / "results" / "d" / "sine" / "linearity.csv")
    assert "Permission denied" in environment_error(denied, own=tmp_path / "results")


def _raise(error: BaseException):
    def writer(*args, **kwargs):
        raise error

    return writer
