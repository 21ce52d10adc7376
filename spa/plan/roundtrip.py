"""The verification session of a round trip, played on a plant: ``spa plan --verify`` of a
dataset's results → the player (its closed-loop staircases through the exported
``controller.h``) compiled with the plant's C twin and closed on it tick by tick → ``spa
record`` writes ``verification.csv`` (:func:`verify_on`); and the stages between a recorded
session and its verification, in memory as the pipeline runs them (:func:`stages_in_memory`).
One sequence for the tests and ``benchmarks/verify_round_trip.py``, on the physical plant or
on spa's model (:func:`spa.plan.host.play_on_plant`)."""

from __future__ import annotations

import argparse
import io
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from spa.plan.host import play_on_plant, session_ticks

__all__ = ["Verification", "stages_in_memory", "verify_on"]


@dataclass(frozen=True)
class Verification:
    """A verification session played and recorded.

    Attributes
    ----------
    folder : pathlib.Path
        The verification plan's folder (its run files and ``verification.csv`` in it).
    log : pathlib.Path
        The player's stream, as the board printed it.
    plan_text, record_text : str
        What ``spa plan --verify`` and ``spa record`` printed.
    frame : pandas.DataFrame
        ``verification.csv``: one row per prediction, its band, measurement and verdict.
    """

    folder: Path
    log: Path
    plan_text: str
    record_text: str
    frame: pd.DataFrame


def _command(argv: list[str], record: bool) -> tuple[int, str]:
    """``spa plan`` or ``spa record`` with ``argv``, as the CLI runs it; its output."""
    from spa.plan.command import plan_arguments, record_arguments, run_plan, run_record

    parser = argparse.ArgumentParser(prog="spa record" if record else "spa plan")
    (record_arguments if record else plan_arguments)(parser)
    buf = io.StringIO()
    args = parser.parse_args(argv)
    code = (run_record if record else run_plan)(args, buf)
    return code, buf.getvalue()


def verify_on(
    folder: str | Path,
    results: str | Path,
    plant: object,
    p_max: float,
    *,
    noise_sd: float | None = None,
    seed: int = 5,
    levels: int = 4,
    baud: int = 250000,
    log: str | Path | None = None,
) -> Verification:
    """Plan the verification of ``results`` into ``folder``, play it on ``plant`` and record.

    Parameters
    ----------
    folder : path
        The new verification folder (``spa plan FOLDER --verify RESULTS``).
    results : path
        The dataset's ``results/<name>`` (identification, and the tuning's recommendation
        and the closed loop's ``controllers.yaml`` and ``controller.h`` when there are).
    plant : ValveParams or spa.synthetic.physical.PhysicalPlant
        What the session is played on: spa's model plant in C, or the physical plant's twin.
    p_max : float
        The actuator's rated maximum, bar (``--p-max``).
    noise_sd : float, optional
        The sensor's noise, bar; the physical plant's own ``noise`` when omitted.
    seed : int, default 5
        Of the noise.
    levels : int, default 4
        Staircase levels (``--levels``).
    baud : int, default 250000
        The link (``--baud``).
    log : path, optional
        Where the stream is written (default: ``<folder>.txt`` beside the folder).

    Returns
    -------
    Verification

    Raises
    ------
    ValueError
        For a model plant without ``noise_sd``, or a valve the model's C twin refuses.
    RuntimeError
        If ``spa plan`` or ``spa record`` fails (with what it printed), or the player does.
    """
    folder = Path(folder)
    sd = getattr(plant, "noise", None) if noise_sd is None else noise_sd
    if sd is None:
        raise ValueError(f"noise_sd: the sensor's noise in bar, for a {type(plant).__name__}")
    argv = [str(folder), "--verify", str(results), "--p-max", f"{p_max:g}"]
    code, plan_text = _command([*argv, "--levels", str(levels), "--baud", str(baud)], False)
    if code != 0:
        raise RuntimeError(f"spa plan {' '.join(argv)} failed:\n{plan_text}")
    noise = np.random.default_rng(seed).normal(0.0, float(sd), session_ticks(folder))
    stream, _ = play_on_plant(folder, plant, noise)
    log = Path(log) if log is not None else folder.parent / f"{folder.name}.txt"
    log.write_text(stream, encoding="ascii")
    code, record_text = _command([str(folder), "--stream", str(log)], True)
    if code != 0:
        raise RuntimeError(f"spa record {folder} --stream {log} failed:\n{record_text}")
    frame = pd.read_csv(folder / "verification.csv")
    return Verification(folder, log, plan_text, record_text, frame)


def stages_in_memory(
    folder: str | Path,
    results: str | Path,
    selected: Iterable[Mapping[str, Any]],
    closed_loop: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """A recorded session's stages, as the pipeline runs them, into ``results``: its runs
    (``runs/``, the canonical tables), identify (``identification/params.yaml``), tune
    (``tuning/recommendation.yaml``) and the closed loop's design, promise and header
    (``closed_loop/controllers.yaml``, ``controller.h``).

    Parameters
    ----------
    folder : path
        The recorded session (``spa record``'s run files, its ``dataset.yaml``).
    results : path
        The new ``results/<name>`` folder.
    selected : iterable of mapping
        The settings the closed loop compares (the config's ``analytic.selected``).
    closed_loop : mapping, optional
        The config's ``closed_loop:`` section.

    Returns
    -------
    dict
        ``identified`` (``params.yaml``'s content), ``recommendation`` and ``promise`` (the
        closed loop's ``bench.promise``, empty when it made none).
    """
    from spa.closedloop.promise import design_for_dataset
    from spa.datasets import ingest_dataset, read_runs
    from spa.identification import identify_with_config
    from spa.identification.identified import read_identified
    from spa.io import dump_yaml
    from spa.tuning import tune

    out = Path(results)
    ingest_dataset(folder, out / "runs")  # as the pipeline's runs stage: the model error's
    runs, metas = read_runs(out / "runs")  # replay reads them (spa plan --verify)
    kinds = {k: m["kind"] for k, m in metas.items()}
    identified = identify_with_config(runs, kinds, metas=metas).to_dict()
    rec = dict(tune(read_identified(identified)).recommendation)
    result, bench = design_for_dataset(identified, runs, metas, selected, closed_loop, rec)
    for sub in ("identification", "tuning", "closed_loop"):
        (out / sub).mkdir(parents=True)
    (out / "identification" / "params.yaml").write_text(dump_yaml(identified))
    (out / "tuning" / "recommendation.yaml").write_text(dump_yaml(rec))
    (out / "closed_loop" / "controllers.yaml").write_text(dump_yaml(result.controllers))
    (out / "closed_loop" / "controller.h").write_text(bench.header)
    promise = (result.controllers.get("bench") or {}).get("promise") or {}
    return {"identified": identified, "recommendation": rec, "promise": promise}
