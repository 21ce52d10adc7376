"""The exact periodic steady state of a modulator setting, by kind.

:func:`periodic_mean` asks the setting's kind (:mod:`spa.model.modulators`) for its orbit,
which the closed forms of :mod:`spa.model.periodic` give: PWM, IPFM and IIPFM through
:func:`~spa.model.periodic.train_mean`, ΔΣM through :func:`~spa.model.periodic.dsm_mean`.
"""

from __future__ import annotations

from typing import Any

import numpy.typing as npt

from spa._docs import fill_doc
from spa.model._broadcast import Floats, as_output, input_fraction
from spa.model.modulators import get_kind
from spa.model.modulators.core import settings_arrays
from spa.model.params import ValveParams, valve_params

__all__ = ["periodic_mean"]


@fill_doc
def periodic_mean(
    kind: str, xi: npt.ArrayLike, params: ValveParams | None = None, **settings: Any
) -> Floats:
    """Exact time mean of the periodic steady state of a modulator at constant ``xi`` (bar).

    Parameters
    ----------
    %(modulator_args)s

    Returns
    -------
    numpy.ndarray or numpy.float64
        PWM, IPFM, IIPFM: :func:`train_mean` of the steady durations (Appendix A); ΔΣM:
        :func:`~spa.model.periodic.dsm_mean` of the true first-order pattern. This is what
        the averaged ``P_eq`` of Eq. 5 approximates.

    Raises
    ------
    ValueError
        For an unknown ``kind`` or a bad setting (named), or a non-finite ``xi``.

    Examples
    --------
    >>> from spa.model.averaging import equilibrium
    >>> exact = periodic_mean("pwm", 0.5, f_w=20.0)
    >>> round(float(exact), 4), round(float(equilibrium("pwm", 0.5, f_w=20.0)), 4)
    (0.28, 0.2789)
    """
    p = valve_params(params)
    s = settings_arrays(kind, settings)
    return as_output(get_kind(kind).periodic_mean(input_fraction(xi), s, p))
