"""The laws refitted without one run, from the fit on every run: the leave-one-run-out
refits of the laws' choice rule (:func:`spa.identification.laws_fit.choose_laws`).

A full refit per held-out run costs a finite-difference Jacobian (one simulation per
coefficient) at every iteration. The fit on every run already holds each run's block of
the Jacobian and its residuals at the optimum, and dropping one run moves the optimum a
little: damped Gauss–Newton steps with that Jacobian (its rows of the other runs), each
checked by one simulation, reach the refit's minimum in a few simulations.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from spa.identification.results import FloatArray
from spa.model.params import ValveParams

if TYPE_CHECKING:
    from spa.identification.laws_fit import LawsFit
    from spa.identification.refine import RefineRun

__all__ = ["LeaveOneOutState", "refit_without"]

#: A step is taken when it lowers the other runs' cost; the refit stops when a step lowers
#: it by less than this fraction.
_RTOL = 1e-3
#: Damping of the first step (0: the undamped step of LawsFit.heldout).
_LAM0 = 1.0


@dataclass(frozen=True)
class LeaveOneOutState:
    """What :func:`refit_without` starts from, kept by :func:`~spa.identification.
    laws_fit.fit_laws` at its optimum.

    Attributes
    ----------
    delay : str
        The delay convention of the fit.
    free : numpy.ndarray
        Indices of the fitted entries of the fit vector.
    lo, hi : numpy.ndarray
        Bounds of every entry of the fit vector.
    weight : numpy.ndarray
        Each run's residual weight (``1/s_r``), in the fit's run order.
    jacobian : numpy.ndarray
        Weighted residuals' Jacobian at the optimum, one row per block mean of every run
        (in order), one column per free entry.
    residuals : numpy.ndarray
        Weighted residuals at the optimum.
    offsets : numpy.ndarray
        Row where each run's block starts, and the total, in the fit's run order.
    """

    delay: str
    free: np.ndarray
    lo: FloatArray
    hi: FloatArray
    weight: FloatArray
    jacobian: FloatArray
    residuals: FloatArray
    offsets: np.ndarray


def refit_without(
    fit: LawsFit, runs: Sequence[RefineRun], rid: str, *, max_nfev: int = 8
) -> ValveParams:
    """The valve of the laws fitted to every run of ``fit`` but ``rid``.

    Parameters
    ----------
    fit : LawsFit
        :func:`~spa.identification.laws_fit.fit_laws` on ``runs``.
    runs : sequence of RefineRun
        The runs of that fit, in its order.
    rid : str
        The run left out.
    max_nfev : int, optional
        Largest number of simulations of the other runs.

    Returns
    -------
    ValveParams
        ``fit.start`` with the refitted laws, ``k2`` and delays.

    Raises
    ------
    ValueError
        If ``runs`` are not the fit's, or ``rid`` is not one of them.

    Notes
    -----
    Levenberg–Marquardt on the other runs' weighted residuals with the full fit's Jacobian
    (their rows): the step solves ``(H + lam*diag(H)) dx = -J'e``, bounds enforced; a step
    that lowers the cost is taken (``lam`` shrinks), one that does not is retried shorter.
    The first step is damped (``lam = 1``): the undamped one, :attr:`LawsFit.heldout`'s,
    overshoots on the compliant balloons and costs a retried simulation.
    """
    from spa.identification.laws_model import _valve, law_model

    st = fit.state
    if st is None or len(runs) + 1 != st.offsets.size:
        raise ValueError(
            f"refit_without: the runs ({len(runs)}) are not the {st.offsets.size - 1 if st else 0}"
            " runs of this fit"
        )
    ids = [r.rid for r in runs]
    if rid not in ids:
        raise ValueError(f"refit_without: run {rid!r} is not one of the fit's runs {ids}")
    j = ids.index(rid)
    keep = np.ones(st.residuals.size, dtype=bool)
    keep[st.offsets[j] : st.offsets[j + 1]] = False
    jac, e = st.jacobian[keep], st.residuals[keep]
    hess = jac.T @ jac
    diag = np.diag(np.maximum(np.diag(hess), 1e-12 * max(float(np.max(np.diag(hess))), 1.0)))
    others = [(r, w) for k, (r, w) in enumerate(zip(runs, st.weight, strict=True)) if k != j]
    knots = fit.laws.knots
    x, cost, lam = fit.x.copy(), float(e @ e), _LAM0
    for _ in range(max_nfev):
        step = np.linalg.lstsq(hess + lam * diag, -(jac.T @ e), rcond=None)[0]
        trial = x.copy()
        trial[st.free] = np.clip(x[st.free] + step, st.lo[st.free], st.hi[st.free])
        prm = _valve(fit.start, trial, knots)
        en = np.concatenate([(law_model(r, prm, st.delay) - r.y) * w for r, w in others])
        cn = float(en @ en)
        if cn < cost:
            done = cost - cn < _RTOL * cost
            x, e, cost, lam = trial, en, cn, lam / 4.0
            if done:
                break
        else:
            lam = max(4.0 * lam, 1e-2)
    return _valve(fit.start, x, knots)
