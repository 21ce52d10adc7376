"""LPWM inverts the valve's averaged equilibrium: on laws it cannot invert (a random
physical plant of the verification's round trip identified such laws, and the tuning
raised from deep inside LPWM's weight table) it is left out by name, not a crash."""

from __future__ import annotations

import numpy as np

from spa.model.laws import Laws
from spa.model.modulators.lpwm import _invertible, law_weights
from spa.model.params import ValveParams
from spa.model.usable import unusable_reason
from spa.tuning import tune
from spa.tuning.cost import DEFAULT_SWEEPS, check_sweeps

#: An exhaust law that dips at mid pressure: its weight B/(A + B) falls there.
DIPPING = ValveParams(
    tau2=1.0, c1=0.5, k2=1.0, laws=Laws(log_g=(0, 0, 0), log_h=(0, -5, 0), knots=(0, 0.5, 1))
)
#: The same valve with laws LPWM inverts.
PLAIN = ValveParams(
    tau2=1.0, c1=0.5, k2=1.0, laws=Laws(log_g=(0, 0, 0), log_h=(0, -0.5, 0), knots=(0, 0.5, 1))
)


def test_lpwm_is_left_out_of_the_tuning_on_laws_it_cannot_invert():
    assert not _invertible(DIPPING) and _invertible(PLAIN)
    assert np.all(np.diff(law_weights({}, PLAIN)) > 0)
    sweeps = {**DEFAULT_SWEEPS, "lpwm": {"start": 1.0, "stop": 76.0, "step": 5.0}}
    assert "lpwm" in check_sweeps(sweeps, PLAIN) and "lpwm" not in check_sweeps(sweeps, DIPPING)
    why = unusable_reason({"type": "lpwm", "f_w": 20.0}, DIPPING)
    assert why is not None and "no inverse" in why and why.startswith("lpwm-20Hz")
    assert unusable_reason({"type": "lpwm", "f_w": 20.0}, PLAIN) is None
    result = tune(DIPPING)  # the paper's four are still tuned
    assert set(result.table2["modulator"]) == {"pwm", "ipfm", "iipfm", "dsm"}
    assert "lpwm" in set(tune(PLAIN).table2["modulator"])
