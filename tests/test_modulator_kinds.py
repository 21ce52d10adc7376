"""Every registered modulator kind through the whole chain, LPWM's inverse, a toy sixth kind."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from spa.model.averaging import equilibrium, pulse_times, time_fractions
from spa.model.modulators import (
    MODULATOR_ORDER,
    REGISTRY,
    Modulator,
    get_kind,
    kinds,
    modulate,
    register,
)
from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.model.steady_state import periodic_mean
from spa.model.thresholds import thresholds
from spa.openloop import staircase_analysis
from spa.plots.style import setting_sort_key
from spa.synthetic import staircase_input
from spa.tuning.cost import DEFAULT_SWEEPS, feasible, linearity_cost, setting

P = ValveParams()
ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("kind", kinds())
def test_every_kind_runs_the_chain(kind):
    spec = get_kind(kind)
    mod = setting(kind, spec.reference, P)
    # modulate -> simulate: a staircase ends above where it starts
    dt = 1e-3
    t = np.arange(11000) * dt
    xi = staircase_input(t, 0.1, 1.0)
    u = mod.modulate(xi, dt)
    assert u.dtype == np.int8 and set(np.unique(u)) <= {0, 1}
    p = simulate(u, dt, P)
    assert p[-1] > p[1000] >= 0.0
    # averaging: fractions in range, equilibrium monotone between 0 and k2
    x = np.linspace(0.0, 1.0, 21)
    a1, a2 = time_fractions(kind, x, P, **mod.settings)
    assert np.all(a1 <= 1.0 + 1e-12) and np.all(a2 <= 1.0 + 1e-12)
    peq = np.asarray(equilibrium(kind, x, P, **mod.settings))
    assert peq[0] == 0.0 and math.isclose(peq[-1], P.k2)
    assert np.all(np.diff(peq) >= -1e-12)
    t_h, t_l = pulse_times(kind, 0.5, P, **mod.settings)
    assert t_h > 0 and t_l > 0
    # the exact orbit's mean is close to the average at 20 Hz / 20 ms
    assert abs(float(periodic_mean(kind, 0.5, P, **mod.settings)) - peq[10]) < 0.05
    # tuning cost and thresholds
    j = float(linearity_cost(kind, spec.reference, P))
    j_exact = float(linearity_cost(kind, spec.reference, P, exact=True))
    assert 0.0 <= j < 15.0 and 0.0 <= j_exact < 15.0
    dead, sat = thresholds(kind, P, **mod.settings)
    assert 0.0 <= dead < sat <= 1.0
    assert bool(feasible(kind, spec.reference, P))
    # label round trip, ordering after the kinds before it
    assert setting_sort_key(mod.label)[:3] == mod.sort_key
    assert Modulator.from_mapping(mod.to_mapping()) == mod
    assert mod.sort_key[0] == MODULATOR_ORDER.index(kind)
    assert set(DEFAULT_SWEEPS[kind]) == {"start", "stop", "step"}


def test_schema_names_the_registered_kinds():
    schema = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
    mod = schema["$defs"]["modulator"]
    assert mod["properties"]["type"]["enum"] == list(kinds())
    for branch in mod["allOf"]:
        kind = branch["if"]["properties"]["type"]["const"]
        spec = get_kind(kind)
        assert set(branch["then"]["properties"]) == {"type", *spec.settings, *spec.optional}
        required = [k for k, v in spec.settings.items() if v is None]
        assert branch["then"]["required"] == required
    assert [b["if"]["properties"]["type"]["const"] for b in mod["allOf"]] == list(kinds())
    props = schema["properties"]
    assert list(props["analytic"]["properties"]["sweeps"]["properties"]) == list(kinds())
    assert list(props["tuning"]["properties"]["ranges"]["properties"]) == list(kinds())


# ---- LPWM -------------------------------------------------------------------------------


@pytest.mark.parametrize("valve", [P, ValveParams(c1=0.4, k2=0.6, tau2=1.1, t_on=0.005, t_off=0.0)])
@pytest.mark.parametrize("f_w", [5.0, 20.0, 50.0])
def test_lpwm_linearises_the_averaged_equilibrium(valve, f_w):
    x = np.linspace(0.0, 1.0, 1001)
    spec = get_kind("lpwm")
    d = spec.duty(x, {"f_w": f_w}, valve)
    inside = (d > 0.0) & (d < 1.0)
    assert inside[1:-1].all()
    peq = np.asarray(equilibrium("lpwm", x, valve, f_w=f_w))
    np.testing.assert_allclose(peq, valve.k2 * x, rtol=0, atol=1e-14)
    # the closed form of the issue, where it is defined
    s = np.sqrt(valve.k2 * x[1:-1])
    rho = (valve.k2 - s * s) / s * valve.c1 / valve.tau2
    d_issue = ((1 - valve.t_off * f_w) + rho * valve.t_on * f_w) / (1 + rho)
    np.testing.assert_allclose(d[1:-1], d_issue, rtol=1e-12)
    assert float(linearity_cost("lpwm", f_w, valve)) < 1e-6
    dead, sat = thresholds("lpwm", valve, f_w=f_w)
    assert dead == pytest.approx(0.0, abs=1e-12) and sat == pytest.approx(1.0)


def test_lpwm_thresholds_with_a_wrong_inverse():
    # the inverse believes t_on = 1 ms while the valve needs 3 ms: a dead-zone opens
    dead, sat = thresholds("lpwm", P, f_w=20.0, t_on=0.001)
    x = np.linspace(0.0, 1.0, 100001)
    _, a2 = time_fractions("lpwm", x, P, f_w=20.0, t_on=0.001)
    assert float(dead) == pytest.approx(x[a2 <= 0].max(), abs=2e-5)
    assert float(sat) == pytest.approx(1.0)


def test_lpwm_binds_the_context_valve():
    m = Modulator.from_mapping({"type": "lpwm", "f_w": 20})
    assert m.label == "lpwm-20Hz" and m.description == "LPWM, f_W = 20 Hz"
    q = ValveParams(c1=0.4)
    bound = m.bind(q)
    assert bound.settings["c1"] == 0.4 and bound.label == m.label
    assert Modulator.from_mapping(bound.to_mapping()) == bound
    x = np.linspace(0, 1, 2000)
    assert not np.array_equal(modulate("lpwm", x, 1e-3, f_w=20), bound.modulate(x, 1e-3))
    # public entry point with the nominal valve by default
    assert np.array_equal(modulate("lpwm", x, 1e-3, f_w=20), m.bind(P).modulate(x, 1e-3))
    with pytest.raises(ValueError, match="c1"):
        Modulator.from_mapping({"type": "lpwm", "f_w": 20, "c1": -1})


def test_lpwm_sensitivity_table():
    from spa.tuning.sensitivity import valve_sensitivity

    intervals = {k: (v * 0.95, v * 1.05) for k, v in P.as_dict().items()}
    table = valve_sensitivity({"type": "lpwm", "f_w": 20.0}, P, intervals, n_xi=50)
    assert len(table) == 1 + 2**5
    assert table["case"].iloc[0] == "estimate"
    assert (table["J_exact"] >= 0).all() and (table["J"].iloc[0] < 1e-6)
    assert table["J"].iloc[1:].max() > 1e-3  # a wrong inverse is no longer exact


# ---- a toy sixth kind -------------------------------------------------------------------


@pytest.fixture
def toy():
    from toy_modulator import Toy

    register(Toy)
    yield get_kind("toy")
    del REGISTRY["toy"]


def test_a_toy_kind_runs_through_tune_and_a_staircase_analysis(toy):
    from spa.tuning import tune

    sweeps = {k: {**g, "step": g["step"] * 20} for k, g in DEFAULT_SWEEPS.items()}
    assert "toy" in sweeps
    result = tune(P, sweeps=sweeps, n_xi=30)
    assert "toy" in set(result.table2["modulator"])
    assert "toy" in set(result.sweeps["modulator"])
    mod = Modulator.from_mapping({"type": "toy", "rate": 20})
    assert mod.label == "toy-20Hz" and setting_sort_key(mod.label)[0] == len(MODULATOR_ORDER) - 1
    dt = 1e-3
    t = np.arange(round(11 * 2.0 / dt)) * dt
    xi = staircase_input(t, 0.1, 2.0)
    u = mod.modulate(xi, dt)
    run = pd.DataFrame({"t": t, "p": simulate(u, dt, P), "valve": u, "u": xi})
    levels, _, summary = staircase_analysis(run, mod, P)
    assert summary["fit"] > 50.0 and len(levels) == 11


# ---- nothing outside spa/model/modulators/ knows a kind by name --------------------------

#: Modules that hold settings as data: the paper's printed ones, the example dataset's, the
#: compliant balloons' short session's.
DATA_MODULES = {"spa/openloop/paper.py", "spa/synthetic/example.py", "spa/synthetic/balloons.py"}


def _kind_strings(path: Path) -> tuple[list[int], list[int]]:
    """Lines of comparisons with a kind's name, and of other non-docstring kind names."""
    tree = ast.parse(path.read_text())
    docs = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }

    def named(node: ast.AST) -> bool:
        return isinstance(node, ast.Constant) and node.value in set(kinds())

    compares = [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Compare)
        and any(named(n) or any(map(named, ast.walk(n))) for n in (node.left, *node.comparators))
    ]
    strings = [node.lineno for node in ast.walk(tree) if named(node) and id(node) not in docs]
    return compares, strings


def test_no_code_outside_the_modulators_package_names_a_kind():
    compares, strings = {}, {}
    for path in sorted((ROOT / "spa").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel.startswith("spa/model/modulators/"):
            continue
        c, s = _kind_strings(path)
        if c:
            compares[rel] = c
        if s and rel not in DATA_MODULES:
            strings[rel] = s
    assert compares == {} and strings == {}
