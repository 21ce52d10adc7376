"""The paper's printed values and its selected settings (Table 2, Section 6).

These numbers are only ever shown beside the measured ones (the ``paper_*`` columns, figure
titles), never used to compute anything.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from spa.model.modulators import Modulator

__all__ = [
    "PAPER_FIG5_ORDER",
    "PAPER_SETTING",
    "PAPER_SETTINGS",
    "PAPER_TABLE2",
    "PAPER_TABLE3",
    "PAPER_TIME_CONSTANTS",
    "paper_case",
]

#: Table 2 as printed in the paper: ``kind -> (J_min, selected parameter, unit)``.
#: Reference values for comparison columns only; nothing here is computed from them.
PAPER_TABLE2: Mapping[str, tuple[float, float, str]] = {
    "pwm": (10.5, 20.0, "Hz"),
    "ipfm": (12.5, 20.0, "ms"),
    "iipfm": (4.8, 20.0, "ms"),
    "dsm": (9.6, 20.0, "ms"),
}

#: The paper's panel order of Fig. 5.
PAPER_FIG5_ORDER: tuple[str, ...] = ("pwm", "ipfm", "dsm", "iipfm")

#: The paper's selected value of each swept parameter (Hz for PWM, s otherwise).
PAPER_SETTING: Mapping[str, float] = {"pwm": 20.0, "ipfm": 0.020, "iipfm": 0.020, "dsm": 0.020}

#: The paper's Table 3 (bench data): case -> (setting, MSE in bar², MD in bar, FIT in %).
#: Its MD is the mean absolute deviation from the line (below sqrt(MSE) in every row), so it
#: is compared with the ``mad`` column, not with the largest deviation ``max_dev``.
PAPER_TABLE3: Mapping[str, tuple[dict[str, Any], float, float, float]] = {
    "PWM": ({"type": "pwm", "f_w": 20.0}, 7.3e-3, 7.56e-2, 75.23),
    "IPFM": ({"type": "ipfm", "t_h": 0.020}, 13.0e-3, 10.02e-2, 68.23),
    "IIPFM (G = 1.00)": ({"type": "iipfm", "t_l": 0.020, "gain": 1.0}, 2.5e-3, 4.07e-2, 84.20),
    "IIPFM (G = 1.15)": ({"type": "iipfm", "t_l": 0.020, "gain": 1.15}, 1.3e-3, 3.13e-2, 87.89),
    "ΔΣM": ({"type": "dsm", "period": 0.020}, 4.5e-3, 5.55e-2, 78.82),
}

#: The settings the paper shows in Figs. 7a, 7b, 8 and 9 (and Table 3), in its order.
PAPER_SETTINGS: tuple[Modulator, ...] = tuple(
    Modulator.from_mapping(case) for case, *_ in PAPER_TABLE3.values()
)

#: The paper's measured step time constants (Fig. 7b): modulator -> (mean, sd) in s.
PAPER_TIME_CONSTANTS: Mapping[str, tuple[float, float]] = {
    "iipfm": (1.139, 0.207),
    "pwm": (0.847, 0.388),
}


def paper_case(mod: Mapping[str, Any] | Modulator) -> str | None:
    """Name of the `PAPER_TABLE3` case a modulator setting is, or None.

    Examples
    --------
    >>> paper_case({"type": "iipfm", "t_l": 0.02, "gain": 1.15})
    'IIPFM (G = 1.15)'
    >>> paper_case({"type": "pwm", "f_w": 10}) is None
    True
    """
    setting = Modulator.from_mapping(mod)
    for name, case in zip(PAPER_TABLE3, PAPER_SETTINGS, strict=True):
        if case == setting:
            return name
    return None
