"""Gain and delay margins of a PI loop on the averaged model linearised at each set-point.

At a set-point the averaged model is a first-order plant with dead time
``G(s) = K exp(-theta s)/(tau s + 1)`` (:func:`spa.closedloop.design.local_models`: the
modulator enters as the gain of ``P_eq`` and as half its pulse period in ``theta``), and the
PI is ``C(s) = Kp + Ki/s``. With ``L = C G``:

* the gain margin is ``1/|L(j w180)|`` at the lowest frequency ``w180`` where the phase of
  ``L`` reaches -180 degrees (the factor by which the loop gain may grow);
* the delay margin is ``PM/wc`` at the gain crossover ``|L(j wc)| = 1``, with
  ``PM = pi + arg L(j wc)`` (the extra dead time the loop tolerates), s.

Both are found on a logarithmic frequency grid refined by bisection.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["loop_margins"]

_W = np.logspace(-4, 5, 4001)  # rad/s


def _loop(w: np.ndarray, k: float, tau: float, theta: float, kp: float, ki: float):
    mag = np.abs(k) * np.hypot(kp * w, ki) / (w * np.hypot(tau * w, 1.0))
    # arg C = atan2(kp*w, ki) - pi/2; arg G = -atan(tau*w) - theta*w
    phase = np.arctan2(kp * w, ki) - 0.5 * math.pi - np.arctan(tau * w) - theta * w
    return mag, phase


def _bisect(f, lo: float, hi: float) -> float:
    flo = f(lo)
    for _ in range(80):
        mid = math.sqrt(lo * hi)
        fm = f(mid)
        if (fm > 0) == (flo > 0):
            lo, flo = mid, fm
        else:
            hi = mid
    return math.sqrt(lo * hi)


def loop_margins(k: float, tau: float, theta: float, kp: float, ki: float) -> tuple[float, float]:
    """Gain margin (factor) and delay margin (s) of a PI on ``K exp(-theta s)/(tau s + 1)``.

    Parameters
    ----------
    k, tau, theta : float
        The plant's gain (bar), time constant (s) and dead time (s).
    kp, ki : float
        The PI's gains, 1/bar and 1/(bar·s).

    Returns
    -------
    gain_margin : float
        ``1/|L|`` at the first -180 degree crossing; ``inf`` when the phase never gets there
        (no dead time).
    delay_margin : float
        ``PM/wc`` at the gain crossover, s; ``inf`` when ``|L|`` never reaches 1, and
        negative when the loop is unstable.

    Examples
    --------
    With ``Ki/Kp = 1/tau`` the PI cancels the pole and ``L = (Kp K/tau) exp(-theta s)/s``:
    crossover ``wc = Kp K/tau``, delay margin ``pi/(2 wc) - theta``, gain margin
    ``pi/(2 theta wc)``.

    >>> gm, dm = loop_margins(0.8, 0.5, 0.05, 2.0, 4.0)  # wc = 3.2 rad/s
    >>> round(gm, 4), round(dm, 4)
    (9.8175, 0.4409)
    """
    mag, phase = _loop(_W, k, tau, theta, kp, ki)
    gm = math.inf
    below = np.flatnonzero(phase <= -math.pi)
    if below.size:
        i = int(below[0])
        lo = float(_W[max(i - 1, 0)])
        w180 = _bisect(lambda w: _loop(np.array([w]), k, tau, theta, kp, ki)[1][0] + math.pi,
                       lo, float(_W[i]))  # fmt: skip
        gm = 1.0 / float(_loop(np.array([w180]), k, tau, theta, kp, ki)[0][0])
    cross = np.flatnonzero(mag <= 1.0)
    if not cross.size:
        return gm, math.inf
    i = int(cross[0])
    if i == 0:
        return gm, math.inf
    wc = _bisect(lambda w: _loop(np.array([w]), k, tau, theta, kp, ki)[0][0] - 1.0,
                 float(_W[i - 1]), float(_W[i]))  # fmt: skip
    pm = math.pi + float(_loop(np.array([wc]), k, tau, theta, kp, ki)[1][0])
    return gm, pm / wc
