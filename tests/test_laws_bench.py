"""Issue 47's fixtures and checks: the compliant balloons as seeded datasets of the full
config, the compliant low-supply class the paired benchmark reports, the pairing itself, a
second state named whichever laws are chosen, and the bundled example keeping the paper's
laws."""

from __future__ import annotations

import dataclasses
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from spa.synthetic.balloons import (
    BALLOON_SEEDS,
    COMPLIANT_GROWTH,
    LOW_SUPPLY,
    compliant_balloons,
    compliant_low_supply,
)
from spa.synthetic.physical import PhysicalPlant

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def _config(name: str = "config.yaml") -> dict:
    return yaml.safe_load((ROOT / "config" / name).read_text(encoding="utf-8"))


@pytest.mark.parametrize("name", sorted(BALLOON_SEEDS))
def test_the_full_config_declares_the_fixture_balloons(name):
    from spa.pipeline.config import validate_config

    cfg = _config()
    validate_config(cfg, str(ROOT / "workflow" / "schemas" / "config.schema.yaml"))
    entry = cfg["simulated"][name]
    assert entry["seed"] == BALLOON_SEEDS[name]
    plant = PhysicalPlant.from_mapping(entry["plant"])
    fixture = compliant_balloons()[name]
    for key, value in dataclasses.asdict(fixture).items():
        assert getattr(plant, key) == pytest.approx(value, rel=1e-9, abs=1e-12), key
    # subsonic both ways over the whole range, and compliant on a low supply
    critical = plant.atmosphere / (plant.atmosphere + plant.supply)
    assert plant.b_supply < critical and plant.b_exhaust < critical
    assert compliant_low_supply(plant.supply, plant.volume, plant.compliance)
    kinds = {m["type"] for m in entry["modulators"]}
    assert kinds == {"pwm", "iipfm", "dsm"}
    # the experiments the validation scores: a sine and a chirp among the runs
    from spa.synthetic.runs import dataset_experiments, dataset_runs

    runs = dataset_runs(entry, dataset_experiments(entry, cfg["experiments"]))
    assert {"sine", "chirp"} <= {r.kind for r in runs}
    assert _config("small.yaml")["simulated"][name] is None


def test_a_datasets_own_seed_replaces_the_config_seed(tmp_path):
    from spa.synthetic.runs import generate_dataset

    base = {
        "params": {"c1": 0.533, "k2": 0.837, "tau2": 0.826, "t_on": 0.003, "t_off": 0.01},
        "controller_dt": 0.001,
        "sensor": {"fs": 1000.0, "noise": 0.005},
        "modulators": [{"type": "pwm", "f_w": 20.0}],
    }
    exp = {"identification": {"charge_time": 0.5, "discharge_time": 0.5, "repeats": 1}}

    def made(cfg: dict, seed: int, where: str) -> list[bytes]:
        paths = generate_dataset("d", cfg, exp, seed, tmp_path / where)
        return [p.read_bytes() for p in paths]

    own = made({**base, "seed": 7}, 1, "own")
    assert own == made(base, 7, "top")
    assert own != made(base, 1, "other")


def test_compliant_low_supply_is_the_issues_class():
    from spa.synthetic.draws import random_plant

    for plant in compliant_balloons().values():
        assert compliant_low_supply(plant.supply, plant.volume, plant.compliance)
    rng = np.random.default_rng(5)
    plants = [random_plant(rng) for _ in range(40)]
    supply = np.array([p.supply for p in plants])
    volume = np.array([p.volume for p in plants])
    compliance = np.array([p.compliance for p in plants])
    got = compliant_low_supply(supply, volume, compliance)
    want = [(s <= LOW_SUPPLY) and (c / v >= COMPLIANT_GROWTH) for s, v, c in zip(
        supply, volume, compliance, strict=True)]  # fmt: skip
    assert got.tolist() == want
    assert 0 < got.sum() < len(plants)  # the draw has both kinds
    with pytest.raises(ValueError, match="volumes must be positive"):
        compliant_low_supply(0.5, 0.0, 10.0)


def _table(fits, verified, kept, laws=None, supply=None) -> pd.DataFrame:
    n = len(fits)
    out = pd.DataFrame(
        {
            "plant": range(n),
            "plant_supply": supply if supply is not None else [0.6, 2.0] * (n // 2),
            "plant_volume": [30.0] * n,
            "plant_compliance": [45.0] * n,
            "heldout_median_fit": fits,
            "verified": verified,
            "kept": kept,
            "error": [""] * n,
        }
    )
    if laws is not None:
        out["laws"] = laws
    return out


def test_the_pairing_reports_each_seeds_verdicts(tmp_path, capsys):
    import physical_pair

    before = _table([60.0, 80.0, 50.0, 90.0], [True, True, False, True],
                    [False, True, False, True])  # fmt: skip
    laws = ["identified", "paper", "identified", "paper"]
    after = _table([85.0, 82.0, 75.0, 89.0], [True] * 4, [True] * 4, laws=laws)
    after.insert(0, "seed", 1)
    b, a = tmp_path / "bench-old-s1.csv", tmp_path / "after.csv"
    before.to_csv(b, index=False)  # an old table: no seed, laws nor class columns
    after.to_csv(a, index=False)
    out_csv = tmp_path / "pair.csv"
    assert physical_pair.main([str(b), str(a), "--csv", str(out_csv)]) == 0
    text = capsys.readouterr().out
    s = pd.read_csv(out_csv).iloc[0]
    compliant = before["plant_supply"] <= LOW_SUPPLY
    diff = after["heldout_median_fit"] - before["heldout_median_fit"]
    assert s["compliant_n"] == compliant.sum()
    assert s["compliant_paired_median_diff"] == pytest.approx(diff[compliant].median())
    assert s["all_paired_median_diff"] == pytest.approx(diff.median())
    assert s["all_fit_before"] == pytest.approx(before["heldout_median_fit"].median())
    assert (s["unverified_before"], s["unverified_after"]) == (1, 0)
    assert (s["broken_before"], s["broken_after"]) == (1, 0)
    assert (s["laws_identified_before"], s["laws_identified_after"]) == (0, 2)
    assert "seed 1: 4 plants, 2 compliant low-supply" in text
    assert f"{diff[compliant].median():+.1f} points (met: >= 10)" in text
    # other plants on the two sides are not a pair
    moved = after.copy()
    moved["plant_supply"] = moved["plant_supply"] * 1.1
    moved.to_csv(a, index=False)
    with pytest.raises(ValueError, match="plant_supply differs between the tables"):
        physical_pair.main([str(b), str(a)])


def _identify_plant(plant: PhysicalPlant, laws: str):
    from spa.identification import identify_with_config
    from spa.synthetic.session import plant_session

    mods = [
        {"type": "pwm", "f_w": 5.0},
        {"type": "iipfm", "t_l": 0.06, "gain": 1.25},
        {"type": "dsm", "period": 0.05},
    ]
    session = plant_session(plant, mods, 1, "two", {"staircase": {"step": 0.1, "hold": 3.0}})
    return identify_with_config(
        session.runs,
        session.kinds,
        {"identification": {"laws": laws}},
        **session.identify_kwargs(),
    ).to_dict()


SECOND_STATES = {
    # wall heat exchange: the gas adiabatic, relaxing to the wall's temperature in 2 s
    "heat": {"heat_tau": 2.0, "polytropic": 1.4},
    # a viscoelastic chamber: half as much volume again creeping in after each change, 2 s
    "creep": {"creep": 15.0, "creep_tau": 2.0},
}


@pytest.mark.parametrize("laws", ["auto", "paper"])
@pytest.mark.parametrize("state", sorted(SECOND_STATES))
def test_a_second_state_is_named_whichever_laws_are_chosen(state, laws):
    plant = dataclasses.replace(compliant_balloons()["balloon-06"], **SECOND_STATES[state])
    d = _identify_plant(plant, laws)
    chosen = d["laws"]["chosen"]
    assert chosen in ("paper", "identified")
    if laws == "paper":
        assert chosen == "paper"
    checks = d["checks"]
    assert not checks["white"]  # Ljung's test, reported as before
    assert {"charge", "discharge"} & {r for r, w in checks["whiteness"].items() if not w["white"]}
    # the sentence naming a second state comes from the history test alone
    hist = checks["history"]
    assert checks["second_state"] and hist["second_state"]
    assert hist["p_history"] < hist["alpha"] and hist["history_share"] >= hist["min_share"]
    named = [s for s in d["warnings"] if "second state" in s]
    assert len(named) == 1 and named[0].startswith("the pressure's rate depends on the time")
    ljung = [s for s in d["warnings"] if "not white" in s]
    assert len(ljung) == 1 and "not laws alone" in ljung[0] and "second state" not in ljung[0]


def test_a_plain_balloon_under_its_identified_laws_has_no_second_state():
    # Ljung's test fails here too (laws and a compromise over runs): it cannot tell this
    # single-state plant from the two above; the history test can.
    d = _identify_plant(compliant_balloons()["balloon-06"], "auto")
    assert d["laws"]["chosen"] == "identified"
    checks = d["checks"]
    assert not checks["white"]
    assert checks["history"] is not None and not checks["second_state"]
    assert not [s for s in d["warnings"] if "second state" in s]
    ljung = [s for s in d["warnings"] if "not white" in s]
    assert len(ljung) == 1 and "not a missing state" in ljung[0]


def test_the_papers_laws_on_a_plain_balloon_are_told_to_depend_on_pressure():
    d = _identify_plant(compliant_balloons()["balloon-06"], "paper")
    hist = d["checks"]["history"]
    assert not hist["second_state"] and hist["pressure_laws"]
    said = [s for s in d["warnings"] if "otherwise than the paper's laws" in s]
    assert len(said) == 1 and "identification.laws: auto" in said[0]


def test_the_bundled_example_keeps_the_papers_laws(tmp_path):
    from spa.datasets import ingest_dataset, read_runs
    from spa.identification import identify_with_config

    copy = tmp_path / "raw" / "example"
    shutil.copytree(ROOT / "raw" / "example", copy)
    ingest_dataset(copy, tmp_path / "runs")
    runs, metas = read_runs(tmp_path / "runs")
    cfg = _config()
    assert cfg["identification"]["laws"] == "auto"
    res = identify_with_config(runs, {k: m["kind"] for k, m in metas.items()}, cfg, metas=metas)
    assert res.laws["chosen"] == "paper", res.laws.get("reason")
    assert res.to_valve_params().laws is None
    # a bench without a second state is not told of one (the history test ran on its runs)
    assert res.checks["history"]["samples"] > 1000 and not res.checks["second_state"]
    assert not [w for w in res.warnings if "second state" in w or "missing state" in w]
    assert not math.isnan(res.to_dict()["k2"]["value"])


def test_a_held_out_refit_from_the_full_fit_reaches_the_refits_prediction():
    from _laws_data import bench_runs

    from spa.identification.laws_fit import fit_laws, law_model
    from spa.identification.laws_heldout import refit_without
    from spa.model.laws import Laws
    from spa.model.params import ValveParams
    from spa.validation import fit_percent

    truth = ValveParams(laws=Laws(log_g=(0.8, 0.0, -0.5, -0.6), log_h=(-0.5, 0.0, 0.4, 0.6), m=0.8))
    runs = bench_runs(truth, np.random.default_rng(5))
    full = fit_laws(runs, ValveParams())
    for held in [r for r in runs if r.modulator][:2]:
        others = [r for r in runs if r.rid != held.rid]
        refit = fit_laws(others, ValveParams(), x0=full.x).params
        quick = refit_without(full, runs, held.rid)
        want = fit_percent(held.y, law_model(held, refit))
        got = fit_percent(held.y, law_model(held, quick))
        assert abs(got - want) < 0.5, (held.rid, got, want)
        assert quick.laws is not None and quick != full.params
    with pytest.raises(ValueError, match="'nope' is not one of the fit's runs"):
        refit_without(full, runs, "nope")
    with pytest.raises(ValueError, match="are not the 6 runs of this fit"):
        refit_without(full, runs[:3], runs[0].rid)
