"""What every modulator kernel shares."""

from __future__ import annotations

from numba import njit

from spa.model.modulators import _EPS

#: The relative tolerance of :mod:`spa.model.modulators` for event times (the same value).
EPS = _EPS


@njit(cache=True)
def integrate_and_fire(  # pragma: no cover
    k: int, x: float, threshold_steps: float, width: float, st
) -> int:
    """One step of an integrator of ``x`` with reset by subtraction that fires pulses.

    ``st = [integral up to t_k in steps, index of the next threshold multiple, end of the
    pulse]``. It fires at step ``k`` when the integral up to ``t_k`` has crossed
    ``(m - eps)*threshold_steps`` (the law of ``spa.model.modulators._firings``); a firing
    starts (or extends) a pulse of ``width`` steps. Returns 1 while the pulse runs.
    """
    while st[0] >= (st[1] - EPS) * threshold_steps:
        st[1] += 1.0
        st[2] = k + width
    st[0] += x
    return 1 if k < st[2] else 0
