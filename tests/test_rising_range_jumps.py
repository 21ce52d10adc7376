"""The range a setting holds has no jump of the averaged equilibrium in it.

Under the transport convention a valve that opens later than it closes stays closed for at
least ``t_on - t_off`` in every PWM period: its modulated ``P_eq`` stops short of ``k2``,
which it reaches only with the valve held open (``xi = 1``). The pressures in between are
not held by modulating; a loop asked for one switches between the valve held open and the
highest modulated pressure.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from spa.closedloop.design import operating_levels
from spa.closedloop.levels import held_range
from spa.model.averaging import equilibrium
from spa.model.modulators import Modulator
from spa.model.params import PHYSICAL_RANGE, ValveParams
from spa.model.usable import JUMP, rising_range

SETTINGS = [
    {"type": "pwm", "f_w": 20.0},
    {"type": "ipfm", "t_h": 0.020},
    {"type": "iipfm", "t_l": 0.020, "gain": 1.15},
    {"type": "dsm", "period": 0.020},
    {"type": "lpwm", "f_w": 20.0},
]


def _log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(math.log(lo), math.log(hi)).map(math.exp)


transport = st.builds(
    ValveParams,
    **{k: _log_uniform(*v) for k, v in PHYSICAL_RANGE.items()},
    delay=st.just("transport"),
)


def _fine(setting: dict, valve: ValveParams, n: int = 20001) -> np.ndarray:
    mod = Modulator.from_mapping(setting).bind(valve)
    xi = np.linspace(0.0, 1.0, n)
    with np.errstate(all="ignore"):
        peq = np.asarray(equilibrium(mod.kind, xi, valve, **mod.settings), dtype=np.float64)
    return peq[np.isfinite(peq)]


def test_pwm_on_a_valve_that_opens_later_than_it_closes_stops_at_its_modulated_top() -> None:
    """t_on - t_off = 15 ms closed in every 50 ms period: the range ends at the highest
    pressure the modulation reaches (xi just below 1), well short of k2."""
    valve = ValveParams(c1=0.03, k2=4.6, tau2=0.05, t_on=0.025, t_off=0.010, delay="transport")
    pwm = {"type": "pwm", "f_w": 20.0}
    _, hi = rising_range(pwm, valve)
    peq = _fine(pwm, valve)
    assert peq[-1] == valve.k2  # held open: the supply
    top = float(peq[:-1].max())  # the highest modulated pressure
    assert hi < 0.9 * valve.k2
    assert math.isclose(hi, top, rel_tol=0.01)
    held = held_range(pwm, valve, 0.95)
    assert held is not None and held[1] < top
    levels, _ = operating_levels(np.linspace(0.1, 0.8, 8) * valve.k2, pwm, valve, 0.95)
    assert max(levels) < top  # no set-point in the jump


def test_the_paper_valve_keeps_its_whole_range() -> None:
    """t_on < t_off: the valve saturates open before xi = 1, continuously; the range
    reaches k2."""
    valve = ValveParams()
    for setting in SETTINGS[:4]:
        _, hi = rising_range(setting, valve)
        assert math.isclose(hi, valve.k2, rel_tol=1e-9), setting


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(valve=transport, setting=st.sampled_from(SETTINGS))
def test_no_jump_within_the_range(valve: ValveParams, setting: dict) -> None:
    """Every pressure of the range is within a jump's size of one the equilibrium takes on
    a grid 50 times finer than the one that found the range."""
    reach = rising_range(setting, valve)
    if reach is None:
        return
    lo, hi = reach
    peq = np.sort(_fine(setting, valve))
    inside = peq[(peq >= lo - 1e-12) & (peq <= hi + 1e-12)]
    assert inside.size >= 2
    gaps = np.diff(np.concatenate(([lo], inside, [hi])))
    assert float(gaps.max()) <= JUMP * valve.k2
