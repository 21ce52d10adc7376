"""Accuracy and error paths of the identification (docs/model.md section 1, paper Section 3.2).

The data are simulated here: the exact model on a fine grid (0.1 ms), sampled at 1 kHz with
Gaussian sensor noise (5 mbar) and 1 mbar ADC quantisation, all seeded. The valve command
changes only at sample instants (the recorded ``valve`` column at sample k is the command
over [t_k, t_{k+1})).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import yaml

from spa import ValveParams, modulate, simulate
from spa.identification import (
    DerivativeFit,
    IdentificationError,
    fit_charge,
    fit_delays,
    fit_discharge,
    identification_commands,
    identify,
    identify_runs,
    load_params,
    pressure_rate,
    simulate_identification,
)
from spa.validation import validate_run

NOMINAL = ValveParams()
OTHER = ValveParams(c1=0.4, k2=1.2, tau2=0.5, t_on=0.005, t_off=0.008)
DT = 1e-3  # sampling step
FINE = 10  # truth simulated at DT / FINE
SIGMA = 0.005  # sensor noise, bar
ADC = 0.001  # quantisation step, bar


def _sensor(p: np.ndarray, rng: np.random.Generator, sigma: float = SIGMA) -> np.ndarray:
    noisy = p + rng.normal(0.0, sigma, p.size)
    return np.round(noisy / ADC) * ADC


def _measure(
    u: np.ndarray, params: ValveParams, p0: float, rng: np.random.Generator, t0: float = 0.0
) -> pd.DataFrame:
    """Truth on the fine grid, sampled at 1 kHz through the sensor model."""
    truth = simulate(np.repeat(u, FINE), DT / FINE, params, p0)[::FINE]
    return pd.DataFrame({"t": t0 + DT * np.arange(u.size), "p": _sensor(truth, rng), "valve": u})


def _experiments(params: ValveParams, seed: int, t0: float = 0.0) -> dict[str, pd.DataFrame]:
    rng = np.random.default_rng(seed)
    cmds = identification_commands(DT)  # charge 5 s, discharge 6 s, pulse ~2.3 s
    return {
        name: _measure(u, params, params.k2 if name == "discharge" else 0.0, rng, t0)
        for name, u in cmds.items()
    }


def _staircase(modulator: dict, params: ValveParams, seed: int) -> pd.DataFrame:
    """xi from 0 to 1 by 0.1 every 5 s through a modulator at 1 kHz."""
    xi = np.repeat(np.round(np.arange(11) * 0.1, 10), int(5.0 / DT))
    settings = {k: v for k, v in modulator.items() if k != "type"}
    u = modulate(modulator["type"], xi, DT, **settings)
    table = _measure(u, params, 0.0, np.random.default_rng(seed))
    table["u"] = xi
    return table


@pytest.fixture(scope="module", params=[NOMINAL, OTHER], ids=["nominal", "other"])
def case(request):
    truth = request.param
    runs = _experiments(truth, seed=11, t0=3.7)
    result = identify(
        {"charge-1": runs["charge"]},
        {"discharge-1": runs["discharge"]},
        {"pulse-1": runs["pulse"]},
        window=0.1,
        polyorder=3,
        seed=5,
    )
    return truth, runs, result


# ---------------------------------------------------------------------------------------------
# Accuracy
# ---------------------------------------------------------------------------------------------


def test_rates_within_2_percent(case):
    truth, _, res = case
    for name in ("c1", "k2", "tau2"):
        est = getattr(res, name).value
        assert abs(est / getattr(truth, name) - 1) < 0.02, (name, est)


def test_delays_within_half_a_millisecond(case):
    truth, _, res = case
    assert abs(res.t_on.value - truth.t_on) < 5e-4, res.t_on
    assert abs(res.t_off.value - truth.t_off) < 5e-4, res.t_off


def test_truth_inside_95_percent_intervals(case):
    truth, _, res = case
    for name in ("c1", "k2", "tau2", "t_on", "t_off"):
        est = getattr(res, name)
        assert est.lo is not None and est.hi is not None
        assert est.lo < est.value < est.hi, name
        assert est.contains(getattr(truth, name)), (name, getattr(truth, name), est.lo, est.hi)


def test_fit_diagnostics(case):
    truth, _, res = case
    assert res.fallback == {}
    assert res.charge.r2 > 0.95 and res.discharge.r2 > 0.95
    assert abs(res.discharge.b - 0.5) < 0.02  # the free power law finds b = 1/2
    assert abs(1 / res.discharge.a - truth.c1) / truth.c1 < 0.03
    assert res.delays.rmse == pytest.approx(SIGMA, rel=0.1)  # residual is the sensor noise
    edges = res.delays.edges
    # a 5 ms low pulse is shorter than t_off: no exhaust, the edge is censored
    short = edges[(edges["direction"] == "off") & (np.isclose(edges["segment"], 0.005))]
    assert short["censored"].all() and len(short) > 0
    spread = res.t_on.spread
    assert spread["n"] >= 10 and 0 < spread["sd"] < 3e-3
    assert abs(spread["median"] - truth.t_on) < 1e-3
    assert res.t_on.runs == ("pulse-1",) and res.k2.runs == ("charge-1",)


@pytest.mark.parametrize(
    "modulator",
    [{"type": "iipfm", "t_l": 0.02, "gain": 1.15}, {"type": "pwm", "f_w": 20.0}],
    ids=["iipfm", "pwm"],
)
def test_staircase_validation_fit(case, modulator):
    truth, _, res = case
    table = _staircase(modulator, truth, seed=3)
    params = res.to_valve_params()
    scored = validate_run(table, params)
    assert scored.fit_percent >= 95.0, scored.as_dict()
    # The same from the input fraction through the modulator (no valve column).
    from_u = validate_run(table.drop(columns="valve"), params, modulator)
    assert from_u.fit_percent == pytest.approx(scored.fit_percent, abs=1e-9)


def test_deterministic_for_a_seed(case):
    _truth, runs, res = case
    again = identify(
        {"charge-1": runs["charge"]},
        {"discharge-1": runs["discharge"]},
        {"pulse-1": runs["pulse"]},
        window=0.1,
        polyorder=3,
        seed=5,
    )
    assert again.to_dict() == res.to_dict()


def test_robust_to_irregular_sampling_offset_and_ringing():
    """Jittered sample times, t not starting at 0, damped ringing after every edge."""
    truth = NOMINAL
    rng = np.random.default_rng(21)
    fine = 100  # truth at 10 us
    runs = {}
    for name, u in identification_commands(DT).items():
        n = u.size
        # sample k at (k*100 + jitter) fine steps, jitter in [-20, 20] (+-0.2 ms)
        idx = np.arange(n) * fine + rng.integers(-20, 21, n)
        idx[0] = 0
        u_fine = u[np.searchsorted(idx, np.arange(idx[-1] + 1), side="right") - 1]
        p0 = truth.k2 if name == "discharge" else 0.0
        p = simulate(u_fine, DT / fine, truth, p0)[idx]
        t = 100.0 + idx * (DT / fine)
        # ringing: 10 mbar, 80 Hz, decaying in 5 ms after each edge
        edges = t[np.flatnonzero(u[1:] != u[:-1]) + 1]
        k = np.searchsorted(edges, t, side="right") - 1
        since = t - edges[np.maximum(k, 0)]
        ring = np.where(k >= 0, 0.01 * np.exp(-since / 0.005) * np.sin(2 * np.pi * 80 * since), 0)
        runs[name] = pd.DataFrame({"t": t, "p": _sensor(p + ring, rng), "valve": u})
    res = identify([runs["charge"]], [runs["discharge"]], [runs["pulse"]], seed=1)
    for name in ("c1", "k2", "tau2"):
        assert abs(getattr(res, name).value / getattr(truth, name) - 1) < 0.02, name
    assert abs(res.t_on.value - truth.t_on) < 1e-3
    assert abs(res.t_off.value - truth.t_off) < 1e-3
    assert res.t_on.runs == ("pulse[0]",)


def test_noise_free_data_give_the_exact_parameters():
    truth = OTHER
    runs = simulate_identification(truth)
    res = identify([runs["charge"]], [runs["discharge"]], [runs["pulse"]], polyorder=3, n_boot=50)
    for name in ("c1", "k2", "tau2"):
        assert getattr(res, name).value == pytest.approx(getattr(truth, name), rel=1e-4)
    assert res.t_on.value == pytest.approx(truth.t_on, abs=1e-6)
    assert res.t_off.value == pytest.approx(truth.t_off, abs=1e-6)


# ---------------------------------------------------------------------------------------------
# Serialisation
# ---------------------------------------------------------------------------------------------


def test_to_dict_is_params_yaml_content(case):
    _truth, _, res = case
    d = res.to_dict()
    text = yaml.safe_dump(d, sort_keys=False)
    back = yaml.safe_load(text)
    for name in ("c1", "k2", "tau2", "t_on", "t_off"):
        assert set(back[name]) >= {"value", "lo", "hi", "unit", "runs", "method", "fallback"}
        assert back[name]["fallback"] is None
    assert back["k2"]["unit"] == "bar" and back["t_on"]["unit"] == "s"
    assert set(back["fits"]["charge"]) == {"slope", "intercept", "r2", "n_points", "window"}
    assert set(back["fits"]["discharge"]) == {"a", "b", "r2_power", "r2", "n_points", "window"}
    assert back["fits"]["discharge"]["window"] == pytest.approx(0.101)  # not shortened
    assert back["fallback"] == {}
    assert back["settings"]["seed"] == 5
    assert load_params(back) == res.to_valve_params()
    assert "spread" in back["t_on"]


def test_identify_runs_sorts_by_kind(case):
    _truth, runs, _res = case
    all_runs = {"a": runs["charge"], "b": runs["discharge"], "c": runs["pulse"], "d": runs["pulse"]}
    kinds = {"a": "charge", "b": "discharge", "c": "pulse", "d": "staircase"}
    out = identify_runs(all_runs, kinds, n_boot=20)
    assert out.k2.runs == ("a",) and out.c1.runs == ("b",) and out.t_on.runs == ("c",)
    with pytest.raises(ValueError, match="kinds has no entry"):
        identify_runs(all_runs, {"a": "charge"})


# ---------------------------------------------------------------------------------------------
# Error paths and fallback
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def nominal_runs():
    return _experiments(NOMINAL, seed=2)


def test_no_charge_run_raises_naming_it(nominal_runs):
    r = nominal_runs
    with pytest.raises(IdentificationError, match="no charge run"):
        identify({}, [r["discharge"]], [r["pulse"]])
    with pytest.raises(IdentificationError, match="no discharge run"):
        identify([r["charge"]], None, [r["pulse"]])
    with pytest.raises(IdentificationError, match="no pulse run"):
        identify([r["charge"]], [r["discharge"]], [])


def test_fallback_is_recorded_never_silent(nominal_runs):
    r = nominal_runs
    nominal = ValveParams(c1=0.5, k2=0.8, tau2=0.8, t_on=0.004, t_off=0.009)
    res = identify(None, [r["discharge"]], [r["pulse"]], fallback=nominal, n_boot=50)
    assert set(res.fallback) == {"k2", "tau2"}
    assert "no charge run" in res.fallback["k2"]
    assert res.k2.value == 0.8 and res.k2.lo is None and res.k2.fallback is not None
    assert res.charge is None and res.discharge is not None
    assert abs(res.c1.value / NOMINAL.c1 - 1) < 0.02  # identified, not the fallback
    # t_on still identified: the pulse fit re-fits k2, tau2 from the weak fallback prior
    assert abs(res.t_on.value - NOMINAL.t_on) < 1e-3
    d = yaml.safe_load(yaml.safe_dump(res.to_dict()))
    assert set(d["fallback"]) == {"k2", "tau2"} and d["k2"]["lo"] is None
    assert res.to_valve_params().k2 == 0.8


def test_pressure_never_near_supply(nominal_runs):
    short = nominal_runs["charge"].iloc[:700]  # valve open for 0.6 s only
    with pytest.raises(IdentificationError, match="never gets near the supply"):
        fit_charge([short])


def test_valve_never_opens_or_closes(nominal_runs):
    closed = nominal_runs["charge"].assign(valve=np.int8(0))
    with pytest.raises(IdentificationError, match="never opens"):
        fit_charge({"x": closed})
    opened = nominal_runs["discharge"].assign(valve=np.int8(1))
    with pytest.raises(IdentificationError, match="never closes"):
        fit_discharge({"y": opened})


def test_too_few_edges(nominal_runs):
    pulse = nominal_runs["pulse"]
    few = pulse[pulse["t"] < 0.5]  # the fill and two short low pulses only
    with pytest.raises(IdentificationError, match=r"falling edge\(s\).*t_off needs at least 3"):
        fit_delays([few], NOMINAL)
    with pytest.raises(IdentificationError, match="has no 'valve' column"):
        fit_delays([pulse.drop(columns="valve")], NOMINAL)


def test_settings_errors_name_the_argument(nominal_runs):
    charge = [nominal_runs["charge"]]
    with pytest.raises(ValueError, match="window"):
        fit_charge(charge, settings=DerivativeFit(window=0.002))
    with pytest.raises(ValueError, match="polyorder"):
        DerivativeFit(polyorder=0)
    with pytest.raises(ValueError, match="supply_fraction"):
        fit_charge(charge, supply_fraction=1.5)
    with pytest.raises(ValueError, match="tail_fraction"):
        fit_discharge([nominal_runs["discharge"]], tail_fraction=0.0)
    with pytest.raises(ValueError, match="n_boot"):
        identify(charge, None, None, n_boot=5)
    with pytest.raises(ValueError, match="max_delay"):
        fit_delays([nominal_runs["pulse"]], NOMINAL, max_delay=-1.0)
    with pytest.raises(ValueError, match="prior_sd"):
        fit_delays([nominal_runs["pulse"]], NOMINAL, prior_sd={"c1": 0.0})
    with pytest.raises(ValueError, match="'p' column"):
        fit_charge([nominal_runs["charge"].drop(columns="p")])


# ---------------------------------------------------------------------------------------------
# Helpers: derivative, experiment design
# ---------------------------------------------------------------------------------------------


def test_pressure_rate_on_irregular_samples():
    rng = np.random.default_rng(0)
    t = 5.0 + np.cumsum(1e-3 + rng.uniform(-1e-4, 1e-4, 2000))
    out = pressure_rate(pd.DataFrame({"t": t, "p": 0.3 * (t - 5.0) ** 2}), 0.05, 2)
    dt = np.diff(out["t"].to_numpy())
    assert np.allclose(dt, dt[0])
    inner = out.iloc[100:-100]
    # linear interpolation of a parabola errs by < dt^2/8 * p'' : the slope stays exact-ish
    assert np.allclose(inner["dpdt"], 0.6 * (inner["t"] - 5.0), atol=1e-3)


def test_identification_commands_layout():
    cmds = identification_commands(0.001, lows=(0.005, 0.05), highs=(0.04,), repeats=3)
    charge, dis, pulse = cmds["charge"], cmds["discharge"], cmds["pulse"]
    assert charge.dtype == np.int8 and charge.size == 5000
    assert np.flatnonzero(np.diff(charge)).tolist() == [99]  # one edge, at 0.1 s
    assert dis[:100].all() and not dis[100:].any() and dis.size == 6000
    edges = np.flatnonzero(np.diff(pulse)) + 1
    assert edges[0] == 100 and edges[1] == 100 + 300  # lead, fill
    seg = np.diff(np.append(edges, pulse.size)).tolist()
    assert seg[1:] == [5, 40, 50, 40] * 3
    with pytest.raises(ValueError, match="dt"):
        identification_commands(0.0)
    with pytest.raises(ValueError, match="lows"):
        identification_commands(0.001, lows=(0.0001,))


def test_simulate_identification_starts():
    runs = simulate_identification(NOMINAL, dt=0.002, charge_duration=3.0)
    assert runs["charge"]["p"].iloc[0] == 0.0
    assert runs["discharge"]["p"].iloc[0] == NOMINAL.k2
    assert len(runs["charge"]) == 1500
    assert math.isclose(runs["pulse"]["t"].iloc[1], 0.002)


def test_figures_build(case, tmp_path):
    from spa.plots.identification import (
        fig2a,
        fig2a_data,
        fig2b,
        fig2b_data,
        fig2c,
        fig2c_data,
        validation_data,
        validation_figure,
    )
    from spa.plots.save import save_figure

    _truth, runs, res = case
    a = fig2a_data(res.charge)
    assert set(a["series"]) == {"measured", "excluded", "fit"}
    b = fig2b_data(res.discharge)
    assert set(b["series"]) == {"measured", "excluded", "power law", "b = 0.5"}
    c = fig2c_data(res.delays.traces["pulse-1"])
    v = validation_data(validate_run(runs["pulse"], res.to_valve_params()))
    for fig, name in (
        (fig2a(a), "a"),
        (fig2b(b), "b"),
        (fig2c(c), "c"),
        (validation_figure(v, "pulse"), "v"),
    ):
        save_figure(fig, tmp_path / f"{name}.png")
        assert (tmp_path / f"{name}.png").stat().st_size > 1000
    with pytest.raises(ValueError, match="lacks column"):
        fig2a(a.drop(columns="dpdt"))
