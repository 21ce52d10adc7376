"""LPWM (model-inverse PWM) as a per-step state machine: PWM whose duty inverts Eq. 5.

At each period start the input fraction is mapped to the duty
``d = (a*(1 - t_off*f_w) + b*t_on*f_w)/(a + b)`` with ``s = sqrt(k2*xi)``, ``a = s*tau2``,
``b = (k2 - s²)*c1`` (0 at ``xi <= 0``, 1 at ``xi >= 1``) for the valve the setting names
(the nominal one for what it omits), then the PWM law of :mod:`.pwm` runs on the duty: the
open-loop LPWM's law, sample for sample. For a valve with its own laws the weight
``w = a/(a + b)`` is read from the valve's table (:func:`spa.model.modulators.lpwm.law_weights`,
appended to the constants) by linear interpolation in ``sqrt(xi)``, as
:func:`spa.model.modulators.lpwm.law_duty` does.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spa.model.modulators.kernels import pwm
from spa.model.params import ValveParams

#: State: PWM's.
INITIAL = pwm.INITIAL

_VALVE = {"c1": 0.533, "k2": 0.837, "tau2": 0.826, "t_on": 0.003, "t_off": 0.010}


def configure(
    settings: dict[str, float], dt: float, params: ValveParams | None = None
) -> np.ndarray:
    """Constants: ``[period, dt, f_w, c1, k2, tau2, t_on, t_off, n]``, followed by the
    ``n + 1`` weights of ``params``' laws (:func:`~spa.model.modulators.lpwm.law_weights`)
    when the valve has its own laws (``n = 0``, nothing follows, for the paper's)."""
    from spa.model.modulators.lpwm import law_weights

    nominal = ValveParams()
    valve = [float(settings.get(k, getattr(nominal, k))) for k in _VALVE]
    f = float(settings["f_w"])
    table = None if params is None else law_weights(settings, params)
    laws = (0.0,) if table is None else (float(table.size - 1), *table)
    return np.array([1.0 / f, dt, f, *valve, *laws])


@njit(cache=True)
def duty(xi: float, cfg: np.ndarray) -> float:  # pragma: no cover
    """The duty that makes the averaged equilibrium ``k2*xi`` for the configured valve."""
    if xi <= 0.0:
        return 0.0
    if xi >= 1.0:
        return 1.0
    f, c1, k2, tau2, t_on, t_off = cfg[2], cfg[3], cfg[4], cfg[5], cfg[6], cfg[7]
    if cfg[8] > 0.0:  # the laws' weight table, cfg[9:], uniform in sqrt(xi)
        n = int(cfg[8])
        j = np.sqrt(xi) * n
        i = min(int(j), n - 1)
        s = j - i
        lo = cfg[9 + i]
        w = lo + s * (cfg[10 + i] - lo)
        d = w * (1.0 - t_off * f) + (1.0 - w) * (t_on * f)
        return min(max(d, 0.0), 1.0)
    root = np.sqrt(k2 * xi)
    a = root * tau2
    b = (k2 - root * root) * c1
    d = (a * (1.0 - t_off * f) + b * (t_on * f)) / (a + b)
    return min(max(d, 0.0), 1.0)


@njit(cache=True)
def step(k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]``: PWM on the duty of ``xi`` (only used at period starts)."""
    return pwm.step(k, duty(xi, cfg), cfg, st)


#: :func:`duty` and :func:`step` in C99: ``int ${p}_mod_step(k, xi, cfg, st)`` (see
#: :mod:`.pwm`); the valve constants are ``cfg[3:8]``.
C_STEP = (
    pwm.C_PWM
    + """
static double ${p}_duty(double xi, const double *cfg)
{
    double f, c1, k2, tau2, t_on, t_off, root, a, b, d;
    if (xi <= 0.0) {
        return 0.0;
    }
    if (xi >= 1.0) {
        return 1.0;
    }
    f = cfg[2];
    c1 = cfg[3];
    k2 = cfg[4];
    tau2 = cfg[5];
    t_on = cfg[6];
    t_off = cfg[7];
    if (cfg[8] > 0.0) {
        /* the laws' weight table, cfg[9..], uniform in sqrt(xi) */
        int n = (int)cfg[8], i;
        double j = sqrt(xi) * (double)n, s, lo, w;
        i = (int)j;
        if (i > n - 1) {
            i = n - 1;
        }
        s = j - (double)i;
        lo = cfg[9 + i];
        w = lo + s * (cfg[10 + i] - lo);
        d = w * (1.0 - t_off * f) + (1.0 - w) * (t_on * f);
        return d < 0.0 ? 0.0 : (d > 1.0 ? 1.0 : d);
    }
    root = sqrt(k2 * xi);
    a = root * tau2;
    b = (k2 - root * root) * c1;
    d = (a * (1.0 - t_off * f) + b * (t_on * f)) / (a + b);
    return d < 0.0 ? 0.0 : (d > 1.0 ? 1.0 : d);
}

static int ${p}_mod_step(long long k, double xi, const double *cfg, double *st)
{
    return ${p}_pwm(k, ${p}_duty(xi, cfg), cfg, st);
}
"""
)
