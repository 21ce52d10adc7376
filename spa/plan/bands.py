"""Verification bands calibrated, not padded: what a verification's 95 % band is made of.

A verification predicts a quantity ``y`` (a level's mean pressure, a staircase's FIT, a
sine's mean or amplitude) on the identified valve; the bench measures it. The two differ by

* the identification's own error: the valve is an estimate. Its joint uncertainty is drawn
  (:func:`parameter_draws`: :data:`DRAWS` valves from the normal approximation of the 95 %
  intervals, the delays by their mean and difference as the identification reports them)
  and pushed through the prediction; the draws' standard deviation is ``sd_params``;
* the model's own error: a single-state valve is not the plant. It is measured on the
  dataset's recorded staircases and sines (:mod:`spa.plan.verify_error`), the sensor noise's
  expected share taken out, and scaled from in-sample to held-out by the identification's
  own leave-one-run-out FIT (:func:`heldout_factor`); its standard deviation ``sd_model``
  carries the degrees of freedom of the levels it was measured on (Kish's effective count:
  replicates of one level share its bias, :func:`effective_count`);
* the sensor: its noise and ADC step on the measured mean, ``(noise**2 + q**2/12)/n``.

The band is ``y ± t_nu * sqrt(sd_params**2 + sd_model**2 + sd_noise**2)``, ``nu`` by
Welch-Satterthwaite (:func:`combine`, :func:`half_width`): a 95 % interval for one
measurement, so that an unchanged plant keeps about 95 % of its predictions. A session of
``m`` predictions breaks some by chance; its verdict uses each prediction's band at the Šidák level
``0.95**(1/m)`` (:func:`session_level`), so that an unchanged plant breaks the session
with probability 5 %.

Before, the band was the worst case over the 32 corners of the box, plus the model's
largest in-sample error, ``1.96 noise/sqrt(n)`` and half an ADC step: on spa's own model the
95th percentile of the errors used 0.02-0.23 of its half-width (issue 63).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt
from scipy import stats

from spa.identification.identified import DELAYS, DIFFERENCE, PARAMETERS
from spa.model.params import ValveParams

__all__ = [
    "DRAWS",
    "LAWS_DRAWS",
    "LEVEL",
    "combine",
    "correlation_of",
    "effective_count",
    "half_width",
    "heldout_factor",
    "parameter_draws",
    "session_level",
]

#: Valves drawn from the identification's uncertainty for each prediction.
DRAWS = 200

#: The draws of a valve with the actuator's own laws: each new law's time map costs some
#: 40-75 ms to build (200 draws would take 8-15 s per planned command); 64 draws estimate
#: the spread's standard deviation to about 9 % (``1/sqrt(2 (n - 1))``).
LAWS_DRAWS = 64

#: The two-sided level of one prediction's band.
LEVEL = 0.95

_Z = float(stats.norm.ppf(0.5 + LEVEL / 2))
_FLOOR = 1e-12


def _split_normal(
    z: npt.NDArray[np.float64], value: float, lo: float, hi: float
) -> npt.NDArray[np.float64]:
    """Standard normal draws ``z`` as draws about ``value`` whose 95 % ends are ``lo`` and
    ``hi`` (a normal each side of ``value``, its scale that side's half-width over 1.96)."""
    up, down = max(hi - value, 0.0) / _Z, max(value - lo, 0.0) / _Z
    return value + np.where(z > 0, z * up, z * down)


#: A correlation record's names that are a valve parameter's (the laws fit's ``log_k2``).
_ALIASES = {"log_c1": "c1", "log_k2": "k2", "log_tau2": "tau2"}


def correlation_of(
    record: Mapping[str, object] | None, names: Sequence[str]
) -> npt.NDArray[np.float64]:
    """The correlation matrix over ``names`` of a ``{"names", "matrix"}`` record (a
    covariance or a correlation: it is normalised; ``log_k2`` stands for ``k2``), made
    positive semi-definite; the identity where the record says nothing.

    Examples
    --------
    >>> rec = {"names": ["log_k2", "t_on"], "matrix": [[4.0, -1.0], [-1.0, 1.0]]}
    >>> correlation_of(rec, ["k2", "tau2", "t_on"]).round(2).tolist()
    [[1.0, 0.0, -0.5], [0.0, 1.0, 0.0], [-0.5, 0.0, 1.0]]
    """
    k = len(names)
    out = np.eye(k)
    if not isinstance(record, Mapping) or not record.get("names"):
        return out
    have = [_ALIASES.get(str(n), str(n)) for n in record["names"]]  # type: ignore[union-attr]
    matrix = np.asarray(record.get("matrix"), dtype=np.float64)
    if matrix.shape != (len(have), len(have)) or not np.isfinite(matrix).all():
        return out
    sd = np.sqrt(np.maximum(np.diag(matrix), 0.0))
    idx = [have.index(n) if n in have and sd[have.index(n)] > 0 else -1 for n in names]
    for i, a in enumerate(idx):
        for j, b in enumerate(idx):
            if i != j and a >= 0 and b >= 0:
                out[i, j] = float(np.clip(matrix[a, b] / (sd[a] * sd[b]), -1.0, 1.0))
    w, v = np.linalg.eigh(out)
    fixed = (v * np.maximum(w, 0.0)) @ v.T
    d = np.sqrt(np.maximum(np.diag(fixed), 1e-300))
    return np.asarray(fixed / np.outer(d, d), dtype=np.float64)


def parameter_draws(
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]] | None,
    n: int | None = None,
    seed: int = 0,
    correlation: Mapping[str, object] | None = None,
) -> list[ValveParams]:
    """``n`` valves drawn from the identification's 95 % intervals.

    Each parameter with an interval is drawn from a normal about the estimate whose 95 %
    ends are the interval's (a split normal where the interval is not symmetric about it).
    ``correlation`` (the refinement's ``correlation`` or the laws fit's ``covariance``
    record) correlates them as the fit does: the intervals give each parameter's spread,
    the fit's covariance how their errors move together (a Gaussian copula). Without it,
    and with ``delay_difference`` beside ``t_on`` and ``t_off``
    (:func:`spa.identification.identified.corners`), the delays are drawn by their mean and
    their difference, as the identification resolves them; else independently. Every draw
    keeps the valve's delay convention and its own laws.

    Parameters
    ----------
    params : ValveParams
        The identified valve (the draws' centre).
    intervals : mapping or None
        ``name -> (lo, hi)``, the 95 % intervals (``ValveParams`` names and
        ``delay_difference``).
    n : int, optional
        :data:`DRAWS`, or :data:`LAWS_DRAWS` for a valve with its own laws.
    seed : int, default 0
        Of the draws: the same valve and seed give the same bands.
    correlation : mapping, optional
        ``{"names": [...], "matrix": [[...]]}`` (:func:`correlation_of`).

    Returns
    -------
    list of ValveParams
        ``n`` valves; empty without intervals.

    Raises
    ------
    ValueError
        For a name that is not a valve parameter.

    Examples
    --------
    >>> v = ValveParams()
    >>> draws = parameter_draws(v, {"k2": (0.95 * v.k2, 1.05 * v.k2)}, n=4000)
    >>> k2 = np.array([d.k2 for d in draws])
    >>> round(float(np.mean(np.abs(k2 - v.k2) <= 0.05 * v.k2)), 2)
    0.95
    >>> box = {"t_on": (0.002, 0.004), "t_off": (0.009, 0.011)}
    >>> tied = {"names": ["t_on", "t_off"], "matrix": [[1.0, 1.0], [1.0, 1.0]]}
    >>> gap = [d.t_off - d.t_on for d in parameter_draws(v, box, n=50, correlation=tied)]
    >>> round(float(np.ptp(gap)), 9)  # errors that move together leave the gap alone
    0.0
    >>> parameter_draws(v, {})
    []
    """
    if not intervals:
        return []
    unknown = sorted(set(intervals) - {*PARAMETERS, DIFFERENCE})
    if unknown:
        raise ValueError(f"intervals: unknown parameter(s) {unknown}; expected {PARAMETERS}")
    if n is None:
        n = DRAWS if params.laws is None else LAWS_DRAWS
    rng = np.random.default_rng(seed)
    names = [name for name in PARAMETERS if name in intervals]
    corr = correlation_of(correlation, names)
    at = [names.index(d) for d in DELAYS if d in names]
    told = len(at) == 2 and corr[at[0], at[1]] != 0.0  # the fit correlates the delays
    paired = not told and DIFFERENCE in intervals and len(at) == 2
    w, v = np.linalg.eigh(corr)
    z = rng.standard_normal((n, len(names))) @ (v * np.sqrt(np.maximum(w, 0.0))).T
    cols: dict[str, npt.NDArray[np.float64]] = {}
    for i, name in enumerate(names):
        if not (paired and name in DELAYS):
            lo, hi = (float(x) for x in intervals[name])
            floor = 0.0 if name in DELAYS else _FLOOR
            cols[name] = np.maximum(_split_normal(z[:, i], getattr(params, name), lo, hi), floor)
    if paired:
        (on_lo, on_hi), (off_lo, off_hi) = intervals["t_on"], intervals["t_off"]
        mean = _split_normal(
            rng.standard_normal(n),
            0.5 * (params.t_on + params.t_off),
            0.5 * (on_lo + off_lo),
            0.5 * (on_hi + off_hi),
        )
        d_lo, d_hi = (float(x) for x in intervals[DIFFERENCE])
        diff = _split_normal(rng.standard_normal(n), params.t_off - params.t_on, d_lo, d_hi)
        cols["t_on"] = np.maximum(mean - 0.5 * diff, 0.0)
        cols["t_off"] = np.maximum(mean + 0.5 * diff, 0.0)
    return [
        dataclasses.replace(params, **{k: float(x[i]) for k, x in cols.items()}) for i in range(n)
    ]


def effective_count(errors: Sequence[float], groups: Sequence[object]) -> float:
    """Kish's effective number of independent errors, when errors of one group (the
    replicates of one setting's level) share a bias: ``N / (1 + (m - 1) rho)``, ``m`` the
    mean group size and ``rho`` the intraclass correlation of one-way ANOVA (clipped to
    [0, 1]).

    Examples
    --------
    >>> effective_count([1.0, 1.0, -1.0, -1.0], ["a", "a", "b", "b"])  # replicates agree
    2.0
    >>> effective_count([1.0, -1.0, 1.0, -1.0], ["a", "a", "b", "b"])  # groups tell nothing
    4.0
    """
    e = np.asarray(errors, dtype=np.float64)
    labels = list(groups)
    n = e.size
    keys = sorted(set(map(str, labels)))
    k = len(keys)
    if n < 2 or k < 2 or k == n:
        return float(n)
    sizes = np.array([sum(str(g) == key for g in labels) for key in keys], dtype=np.float64)
    means = np.array([e[[str(g) == key for g in labels]].mean() for key in keys])
    grand = e.mean()
    ss_between = float(np.sum(sizes * (means - grand) ** 2))
    ss_within = float(
        sum(
            np.sum((e[[str(g) == key for g in labels]] - m) ** 2)
            for key, m in zip(keys, means, strict=True)
        )
    )
    ms_between = ss_between / (k - 1)
    ms_within = ss_within / (n - k)
    m0 = (n - float(np.sum(sizes**2)) / n) / (k - 1)
    den = ms_between + (m0 - 1.0) * ms_within
    rho = (ms_between - ms_within) / den if den > 0 else 1.0
    rho = min(max(rho, 0.0), 1.0)
    return float(n / (1.0 + (n / k - 1.0) * rho))


def heldout_factor(heldout: Mapping[str, float], insample: Mapping[str, float]) -> float:
    """How much larger the model's error is on runs it was not fitted to: the median over
    the runs of ``(100 - FIT held out) / (100 - FIT in sample)`` (the FIT's complement is
    the error's norm), at least 1; 1 without a run that has both.

    Examples
    --------
    >>> heldout_factor({"a": 98.0, "b": 96.0}, {"a": 99.0, "b": 98.0})
    2.0
    >>> heldout_factor({}, {})
    1.0
    """
    ratios = []
    for rid, held in heldout.items():
        inner = insample.get(rid)
        try:
            h, i = float(held), float(inner)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            continue
        if math.isfinite(h) and math.isfinite(i) and i < 100.0:
            ratios.append((100.0 - h) / (100.0 - i))
    return max(float(np.median(ratios)), 1.0) if ratios else 1.0


def combine(
    sd_params: npt.ArrayLike, sd_model: float, dof_model: float, sd_noise: npt.ArrayLike
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """A prediction's standard deviation, the three terms' root sum of squares, and its
    degrees of freedom by Welch-Satterthwaite (the draws' and the noise's terms known, the
    model's with ``dof_model``; infinite without a model term).

    Examples
    --------
    >>> sd, nu = combine(0.0, 1.0, 4.0, 1.0)
    >>> round(float(sd), 4), round(float(nu), 1)
    (1.4142, 16.0)
    """
    p = np.asarray(sd_params, dtype=np.float64) ** 2
    s = np.asarray(sd_noise, dtype=np.float64) ** 2
    m = float(sd_model) ** 2
    total = p + s + m
    if m > 0 and math.isfinite(float(dof_model)):
        nu = total**2 / (m**2 / max(float(dof_model), 1.0))
    else:
        nu = np.full_like(total, np.inf)
    return np.sqrt(total), np.asarray(nu, dtype=np.float64)


def half_width(
    sd: npt.ArrayLike, dof: npt.ArrayLike, level: float = LEVEL
) -> npt.NDArray[np.float64]:
    """A band's half-width at ``level``: ``t_nu`` (the normal's quantile where ``nu`` is
    infinite) times ``sd``.

    Examples
    --------
    >>> round(float(half_width(1.0, np.inf)), 3), round(float(half_width(1.0, 4.0)), 3)
    (1.96, 2.776)
    """
    nu = np.asarray(dof, dtype=np.float64)
    q = stats.t.ppf(0.5 + level / 2, np.where(np.isfinite(nu), nu, 1e12))
    return np.asarray(q * np.asarray(sd, dtype=np.float64), dtype=np.float64)


def session_level(m: int, level: float = LEVEL) -> float:
    """Each prediction's level at which a session of ``m`` predictions, on an unchanged
    plant, keeps all of them with probability ``level`` (Šidák: ``level**(1/m)``).

    Examples
    --------
    >>> round(session_level(20), 5)
    0.99744
    """
    return float(level ** (1.0 / max(int(m), 1)))
