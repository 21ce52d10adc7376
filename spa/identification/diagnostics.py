"""Checks of an identified model that a statistician would ask for, and the sensor's own noise.

* :func:`whiteness`: Ljung's whiteness test of a run's residuals. A model that captures the
  valve leaves residuals that are the sensor's noise, uncorrelated from sample to sample; a
  state the model lacks (heat exchange, a creeping wall, a lagging line) leaves slow,
  correlated residuals. The test compares the residual autocorrelation at lags ``1..M``
  with the band ``±2.58/sqrt(N)`` (99 %) and decides on the Ljung–Box statistic
  ``Q = N(N+2) Σ r_k²/(N-k)`` against χ²(M) at level ``alpha`` (Ljung, *System
  Identification*, 2nd ed., §16.6).
* :func:`repeats_agree`: the repeats of one experiment (five charges, five discharges)
  estimate the same parameter; their per-run estimates must agree within their standard
  errors: ``χ² = Σ (θ_j - θ̄)²/se_j²`` (θ̄ the inverse-variance mean) against χ²(n-1). A
  throttled vent, a kinked line or a run started elsewhere stands out.
* :func:`sensor_noise`: the sensor's noise where nothing moves (a settled plateau), never the
  residual of a fit (model error included), and never the zero tail (gauge sensors clip there).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import chdtri

from spa.identification.results import FloatArray

__all__ = [
    "RepeatsCheck",
    "Whiteness",
    "repeats_agree",
    "second_difference_sd",
    "sensor_noise",
    "whiteness",
]

#: Two-sided 99 % normal quantile: Ljung's band for one autocorrelation coefficient.
BAND_Z = 2.58


@dataclass(frozen=True)
class Whiteness:
    """Ljung's whiteness test of one run's residuals.

    Attributes
    ----------
    run : str
        Run id.
    n : int
        Residuals tested.
    lags : int
        Autocorrelation lags ``M`` tested.
    q : float
        Ljung–Box statistic.
    q_limit : float
        χ²(M) quantile the statistic is compared with.
    outside : tuple of int
        Lags whose autocorrelation lies outside ``±2.58/sqrt(n)``.
    white : bool
        ``q <= q_limit``.
    """

    run: str
    n: int
    lags: int
    q: float
    q_limit: float
    outside: tuple[int, ...]
    white: bool

    def to_dict(self) -> dict[str, object]:
        """Plain mapping for ``params.yaml``."""
        return {
            "n": self.n,
            "lags": self.lags,
            "q": round(float(self.q), 3),
            "q_limit": round(float(self.q_limit), 3),
            "lags_outside_band": list(self.outside),
            "white": bool(self.white),
        }


def whiteness(run: str, residuals: FloatArray, alpha: float = 0.01, lags: int = 20) -> Whiteness:
    """Ljung's whiteness test of ``residuals``.

    Parameters
    ----------
    run : str
        The run's id (carried into the result).
    residuals : numpy.ndarray
        Model residuals in time order.
    alpha : float, optional
        Level of the test (a white sequence fails it with probability ``alpha``).
    lags : int, optional
        Largest lag tested; at most a quarter of the residuals.

    Returns
    -------
    Whiteness
        ``white`` is True for fewer than 8 residuals (nothing can be told).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> whiteness("a", rng.normal(size=2000)).white
    True
    >>> whiteness("b", np.cumsum(rng.normal(size=2000))).white
    False
    """
    e = np.asarray(residuals, dtype=np.float64)
    e = e[np.isfinite(e)]
    n = e.size
    m = int(min(lags, n // 4))
    if n < 8 or m < 1:
        return Whiteness(run, n, 0, 0.0, math.inf, (), True)
    e = e - e.mean()
    den = float(np.dot(e, e))
    if den <= 0.0:
        return Whiteness(run, n, m, 0.0, math.inf, (), True)
    r = np.array([float(np.dot(e[:-k], e[k:])) / den for k in range(1, m + 1)])
    q = float(n * (n + 2) * np.sum(r * r / (n - np.arange(1, m + 1))))
    limit = float(chdtri(m, alpha))
    outside = tuple(int(k) for k in np.flatnonzero(np.abs(r) > BAND_Z / math.sqrt(n)) + 1)
    return Whiteness(run, n, m, q, limit, outside, q <= limit)


@dataclass(frozen=True)
class RepeatsCheck:
    """Whether the repeats of one experiment agree on a parameter.

    Attributes
    ----------
    parameter : str
        The parameter (``"c1"``, ``"k2"``, ``"tau2"``).
    estimates, se : mapping
        Run id → the run's own estimate and its standard error.
    mean : float
        Inverse-variance weighted mean.
    chi2, limit : float
        The statistic and its χ²(n-1) quantile at the test's level.
    agree : bool
        ``chi2 <= limit``.
    outlier : str
        The run contributing most to ``chi2`` (``""`` when they agree).
    """

    parameter: str
    estimates: Mapping[str, float]
    se: Mapping[str, float]
    mean: float
    chi2: float
    limit: float
    agree: bool
    outlier: str

    def sentence(self) -> str:
        """The verdict in words (``""`` when the repeats agree).

        Examples
        --------
        >>> RepeatsCheck("c1", {"a": 0.1, "b": 2.0}, {"a": 0.01, "b": 0.05}, 0.17, 900.0,
        ...              6.6, False, "b").sentence()[:60]
        'the repeats disagree on c1: run b gives 2, the others 0.1 (χ'
        """
        if self.agree:
            return ""
        others = [v for k, v in self.estimates.items() if k != self.outlier]
        rest = f"{np.median(others):.3g}" if others else "nothing"
        return (
            f"the repeats disagree on {self.parameter}: run {self.outlier} gives "
            f"{self.estimates[self.outlier]:.3g}, the others {rest} (χ² = {self.chi2:.3g} "
            f"against {self.limit:.3g} for {len(self.estimates) - 1} degree(s) of freedom): "
            "check that run (a throttled or kinked line, another supply, a run started "
            "elsewhere)"
        )

    def to_dict(self) -> dict[str, object]:
        """Plain mapping for ``params.yaml``."""
        return {
            "estimates": {k: float(v) for k, v in self.estimates.items()},
            "se": {k: float(v) for k, v in self.se.items()},
            "chi2": round(float(self.chi2), 3),
            "limit": round(float(self.limit), 3),
            "agree": bool(self.agree),
            "outlier": self.outlier,
        }


def repeats_agree(
    parameter: str,
    estimates: Mapping[str, float],
    se: Mapping[str, float],
    alpha: float = 0.01,
    floor: float = 0.0,
) -> RepeatsCheck | None:
    """χ² test that the repeats' estimates of ``parameter`` agree within their errors.

    Parameters
    ----------
    parameter : str
        Its name.
    estimates, se : mapping
        Run id → the run's estimate and standard error (runs with a non-finite value or
        error are left out).
    alpha : float, optional
        Level of the test.
    floor : float, optional
        Relative standard error every repeat is given at least (run-to-run variation a bench
        always has: temperature, supply drift), as a fraction of the mean.

    Returns
    -------
    RepeatsCheck or None
        None with fewer than two usable repeats.

    Examples
    --------
    >>> repeats_agree("c1", {"a": 0.50, "b": 0.51, "c": 0.49}, {"a": .01, "b": .01, "c": .01}).agree
    True
    >>> se = {"a": .01, "b": .01, "c": .01}
    >>> repeats_agree("c1", {"a": 0.50, "b": 0.51, "c": 0.9}, se).outlier
    'c'
    """
    keys = [
        k
        for k in estimates
        if math.isfinite(estimates[k]) and math.isfinite(se.get(k, math.nan)) and se[k] > 0
    ]
    if len(keys) < 2:
        return None
    x = np.array([estimates[k] for k in keys])
    s = np.array([se[k] for k in keys])
    s = np.maximum(s, floor * abs(float(np.median(x))))
    w = 1.0 / s**2
    mean = float(np.sum(w * x) / np.sum(w))
    terms = w * (x - mean) ** 2
    chi2 = float(terms.sum())
    limit = float(chdtri(len(keys) - 1, alpha))
    agree = chi2 <= limit
    outlier = "" if agree else keys[int(np.argmax(terms))]
    return RepeatsCheck(
        parameter,
        {k: float(v) for k, v in zip(keys, x, strict=True)},
        {k: float(v) for k, v in zip(keys, s, strict=True)},
        mean,
        chi2,
        limit,
        agree,
        outlier,
    )


def second_difference_sd(p: FloatArray) -> float:
    """Noise standard deviation from second differences (MAD), in the unit of ``p``: exact
    for white noise on a straight line, an upper bound where the record curves.

    Examples
    --------
    >>> second_difference_sd(np.arange(10.0))
    0.0
    >>> bool(np.isnan(second_difference_sd(np.zeros(2))))
    True
    """
    d2 = np.diff(p, 2)
    if d2.size == 0:
        return math.nan
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    return 1.4826 * mad / math.sqrt(6.0)


def sensor_noise(
    plateaus: Sequence[FloatArray], moving: Sequence[FloatArray], min_samples: int = 8
) -> tuple[float, str, bool]:
    """The sensor's noise standard deviation, estimated where nothing moves.

    Parameters
    ----------
    plateaus : sequence of numpy.ndarray
        Stretches where the pressure is settled away from 0 (a charge run's settled tail
        near the supply, a still staircase level): their standard deviation about their
        own straight line is the noise, pooled over the stretches.
    moving : sequence of numpy.ndarray
        Other pressure records, used only when no plateau is long enough: their
        second-difference MAD, an upper bound (curvature and edges add to it).
    min_samples : int, optional
        Samples a plateau needs to count.

    Returns
    -------
    sd : float
        Bar (NaN when nothing is long enough).
    method : str
        How it was found.
    upper_bound : bool
        Whether ``sd`` is only an upper bound.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> sd, how, bound = sensor_noise([0.8 + 0.004 * rng.normal(size=4000)], [])
    >>> bool(abs(sd - 0.004) < 0.0002), bound
    (True, False)
    """
    ss = 0.0
    dof = 0
    used = 0
    for seg in plateaus:
        seg = np.asarray(seg, dtype=np.float64)
        if seg.size < min_samples:
            continue
        x = np.arange(seg.size, dtype=np.float64)
        coef = np.polyfit(x, seg, 1)
        r = seg - np.polyval(coef, x)
        ss += float(np.dot(r, r))
        dof += seg.size - 2
        used += 1
    if dof > 0:
        sd = math.sqrt(ss / dof)
        return sd, f"standard deviation about the line of {used} settled plateau(s)", False
    sds = [second_difference_sd(np.asarray(p, dtype=np.float64)) for p in moving if len(p) > 8]
    sds = [s for s in sds if math.isfinite(s)]
    if not sds:
        return math.nan, "no record long enough", True
    return (
        float(np.median(sds)),
        "second-difference MAD of the records (no settled plateau): an upper bound",
        True,
    )
