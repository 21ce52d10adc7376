"""The actuator's own laws in the identification: chosen only where the held-out modulated runs
demand them, recorded in params.yaml, and read back by the stages that replay the model."""

from __future__ import annotations

import numpy as np
import pytest

from spa.identification import identify_with_config, load_params
from spa.identification.identified import read_identified
from spa.model.params import ValveParams
from spa.synthetic.balloons import SHORT_SESSION

MODULATORS = SHORT_SESSION["modulators"]
EXPERIMENTS = SHORT_SESSION["experiments"]


def _dataset(tmp_path, cfg: dict, name: str, seed: int):
    from spa.datasets import read_runs
    from spa.synthetic.runs import generate_dataset

    generate_dataset(name, cfg, EXPERIMENTS, seed, tmp_path / name)
    runs, metas = read_runs(tmp_path / name)
    return runs, {r: m["kind"] for r, m in metas.items()}, metas


@pytest.fixture(scope="module")
def balloon(tmp_path_factory):
    from spa.synthetic.balloons import BALLOON_SEEDS, compliant_balloons

    plant = compliant_balloons()["balloon-06"]
    cfg = {
        "plant": {"kind": "physical", **plant.to_mapping()},
        "controller_dt": 0.001,
        "sensor": {"fs": 1000.0},
        "modulators": MODULATORS,
    }
    runs, kinds, metas = _dataset(tmp_path_factory.mktemp("b"), cfg, "balloon-06",
                                  BALLOON_SEEDS["balloon-06"])  # fmt: skip
    return identify_with_config(runs, kinds, {}, metas=metas)


def test_a_compliant_balloon_chooses_its_own_laws(balloon) -> None:
    laws = balloon.laws
    assert laws["chosen"] == "identified", laws["reason"]
    assert laws["gain"] > 2.0 and laws["gain"] > 2.0 * laws["se"]
    held = laws["fit_identified"]
    assert set(held) == set(laws["fit_paper"]) and len(held) == 6
    # paired per run: the identified laws predict most held-out runs better
    better = sum(held[r] > laws["fit_paper"][r] for r in held)
    assert better >= 5
    names = laws["covariance"]["names"]
    assert len(laws["covariance"]["matrix"]) == len(names)
    assert "actuator's own laws describe the modulated runs better" in balloon.adequacy["sentence"]


def test_params_yaml_carries_the_laws_to_every_stage(balloon) -> None:
    d = balloon.to_dict()
    valve = load_params(d)
    assert valve.laws is not None and not valve.laws.is_paper
    assert valve.k2 == pytest.approx(d["laws"]["valve"]["k2"])
    ident = read_identified(d)
    assert ident.params == valve  # the stages design on the laws the identification chose
    # both delays are read at the command edges and the laws' fit holds them: the balloon's
    # dead times plus half its spool's transit and its sensor's lag, 18.5 and 28.5 ms
    assert d["delay_convention"]["chosen_by"].startswith("the command edges")
    assert not ident.unresolved
    for name, truth in (("t_on", 0.0185), ("t_off", 0.0285)):
        assert d["laws"]["valve"][name] == d[name]["value"]
        assert abs(d[name]["value"] - truth) < 1e-3, name
    assert ident.laws == d["laws"]["coefficients"]
    assert balloon.to_valve_params() == valve
    # the box: c1 and tau2 from the bands' envelopes, around the laws valve's own values
    for name in ("c1", "tau2", "k2", "t_on", "t_off"):
        lo, hi = ident.intervals[name]
        assert lo < getattr(valve, name) < hi, name
    assert ident.intervals["tau2"] != (d["tau2"]["lo"], d["tau2"]["hi"])
    # the adequacy the stages consult is the chosen model's held-out FIT
    held = d["laws"]["fit_identified"]
    assert ident.adequacy["heldout_fit"]["median"] == pytest.approx(
        float(np.median(list(held.values()))), abs=1e-3
    )
    # the bands and the pressures visited are recorded, each mode's band around its rate
    bands, visited = d["laws"]["bands"], d["laws"]["visited"]
    grid = np.array(bands["grid"])
    assert grid.size == 41 and 0 < grid[0] < grid[-1] < valve.k2
    for mode in ("open", "closed"):
        rate, lo, hi = (np.array(bands[mode][k], float) for k in ("rate", "lo", "hi"))
        ok = np.isfinite(lo)
        assert ok.sum() > 30 and np.all(lo[ok] <= rate[ok]) and np.all(rate[ok] <= hi[ok])
        assert 0.0 <= visited[mode][0] < visited[mode][1] <= 1.05 * valve.k2


def test_the_paper_valve_keeps_the_papers_laws_without_fitting(tmp_path) -> None:
    cfg = {
        "params": ValveParams().as_dict(),
        "controller_dt": 0.001,
        "sensor": {"fs": 1000.0, "noise": 0.004, "quantum": 0.001},
        "modulators": MODULATORS,
    }
    runs, kinds, metas = _dataset(tmp_path, cfg, "paper", 3)
    res = identify_with_config(runs, kinds, {}, metas=metas)
    assert res.laws["chosen"] == "paper"
    assert "none were fitted" in res.laws["reason"]
    assert res.to_valve_params().laws is None
    forced = identify_with_config(runs, kinds, {"identification": {"laws": "paper"}}, metas=metas)
    assert forced.laws == {"chosen": "paper", "setting": "paper",
                           "reason": "identification.laws: paper"}  # fmt: skip
    with pytest.raises(ValueError, match=r"identification\.laws must be auto or paper"):
        identify_with_config(runs, kinds, {"identification": {"laws": "mine"}}, metas=metas)


def test_laws_change_the_averaged_equilibrium_only_when_carried() -> None:
    from spa.model.averaging import equilibrium
    from spa.model.laws import Laws

    own = ValveParams(laws=Laws(log_g=(0, 0.3, 0.5, 0.6), log_h=(0, -0.2, -0.4, -0.5), m=0.7))
    xi = np.array([0.2, 0.5])
    assert not np.allclose(equilibrium("pwm", xi, own, f_w=20.0),
                           equilibrium("pwm", xi, ValveParams(), f_w=20.0))  # fmt: skip
    same = ValveParams(laws=Laws())  # the paper's laws: the valve's default form
    assert same.laws is None
    np.testing.assert_array_equal(
        equilibrium("pwm", xi, same, f_w=20.0), equilibrium("pwm", xi, ValveParams(), f_w=20.0)
    )
