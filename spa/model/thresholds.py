"""Dead-zone and saturation thresholds of the input fraction (docs/model.md section 3, Table 1).

* :func:`thresholds` – the largest ``xi`` of the dead-zone and the smallest of saturation,
  the zero crossings of the averaged time fractions;
* :func:`threshold_table` – Table 1 for a list of modulator settings;
* :data:`THRESHOLD_FORMULAS` – the same closed forms as text, for the table.

Vectorised like :mod:`spa.model.averaging`: settings may be arrays.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from typing import Any

import numpy as np
import pandas as pd

from spa._docs import fill_doc
from spa.model._broadcast import Floats, as_output
from spa.model.modulators import MODULATOR_ORDER, REGISTRY, Modulator, get_kind
from spa.model.modulators.core import settings_arrays
from spa.model.params import ValveParams, valve_params

__all__ = ["THRESHOLD_FORMULAS", "threshold_table", "thresholds"]


#: Table 1 as text: ``kind -> (dead-zone, saturation)`` closed forms of ``xi`` (clipped to
#: [0, 1]). The ΔΣM forms reduce to the paper's 0 and 1 when ``period >= 2*t_on, 2*t_off``.
class _Formulas(Mapping[str, tuple[str, str]]):
    def __getitem__(self, kind: str) -> tuple[str, str]:
        return REGISTRY[kind].threshold_formulas

    def __iter__(self) -> Iterator[str]:
        return iter(MODULATOR_ORDER)

    def __len__(self) -> int:
        return len(REGISTRY)


THRESHOLD_FORMULAS: Mapping[str, tuple[str, str]] = _Formulas()


@fill_doc
def thresholds(
    kind: str, params: ValveParams | None = None, **settings: Any
) -> tuple[Floats, Floats]:
    """Dead-zone and saturation thresholds of the input fraction (Table 1).

    Parameters
    ----------
    %(kind)s
    params : ValveParams, optional
        Valve parameters (``t_on``, ``t_off``); nominal when omitted.
    **settings
        Modulator settings as in :func:`pulse_times` (scalars or arrays).

    Returns
    -------
    dead_zone, saturation : numpy.ndarray or numpy.float64
        ``dead_zone``: the largest ``xi`` in [0, 1] with ``alpha2(xi) <= 0`` (``P_eq = 0`` up
        to it). ``saturation``: the smallest ``xi`` in [0, 1] with ``alpha1(xi) <= 0``
        (``P_eq = k2`` from it); 1 when the actuator saturates only at ``xi = 1`` or never.

    Raises
    ------
    ValueError
        For an unknown ``kind`` or a setting out of its range (checked by
        :func:`time_fractions`).

    Notes
    -----
    The zero crossings of the fractions of :func:`time_fractions`, clipped to [0, 1]:

    =======  =================================  ==================================
    kind     dead-zone                          saturation
    =======  =================================  ==================================
    PWM      ``t_on*f_w``                       ``1 - t_off*f_w``
    IPFM     0 (1 if ``t_h <= t_on``)           ``G*t_h/(t_h + t_off)``
    IIPFM    ``1 - G/(1 + t_on/t_l)``           1 (0 if ``t_l <= t_off``)
    ΔΣM      ``1 - T_DS/(2*t_on)``              ``T_DS/(2*t_off)``
    LPWM     0 (inverse of the plant's valve)   1 (inverse of the plant's valve)
    =======  =================================  ==================================

    These are Table 1 of the paper (with ``G = 1`` for IPFM). For ΔΣM the paper prints 0
    and 1, which is what the formulas give when ``T_DS >= 2*t_on`` and ``T_DS >= 2*t_off``;
    for ``t_off < T_DS < 2*t_off`` the averaged fractions (built on the paper's approximate
    firing frequency ``2*xi*(1 - xi)/T_DS``) saturate before ``xi = 1``.

    Examples
    --------
    >>> p = ValveParams()
    >>> [round(float(v), 6) for v in thresholds("pwm", p, f_w=20.0)]
    [0.06, 0.8]
    >>> [round(float(v), 6) for v in thresholds("iipfm", p, t_l=0.02, gain=1.15)]
    [0.0, 1.0]
    """
    p = valve_params(params)
    s = settings_arrays(kind, settings)
    dead, sat = get_kind(kind).thresholds(s, p)
    return (
        as_output(np.clip(np.asarray(dead, np.float64), 0.0, 1.0)),
        as_output(np.clip(np.asarray(sat, np.float64), 0.0, 1.0)),
    )


@fill_doc
def threshold_table(
    selected: Iterable[Mapping[str, Any] | Modulator], params: ValveParams | None = None
) -> pd.DataFrame:
    """Table 1 for a list of modulator settings, as a tidy table.

    Parameters
    ----------
    selected : iterable of mapping or Modulator
        Entries like ``{"type": "iipfm", "t_l": 0.02, "gain": 1.15}`` (the ``analytic.selected``
        section of the configuration) or :class:`~spa.model.modulators.Modulator` values.
    %(params)s

    Returns
    -------
    pandas.DataFrame
        One row per entry: ``modulator``, ``settings`` (``name=value`` pairs, defaults filled
        in), ``dead_zone_formula``, ``dead_zone``, ``saturation_formula``, ``saturation``.

    Raises
    ------
    ValueError
        If an entry has no ``type`` or bad settings.

    Examples
    --------
    >>> threshold_table([{"type": "pwm", "f_w": 20.0}])[["dead_zone", "saturation"]].round(6)
       dead_zone  saturation
    0       0.06         0.8
    """
    p = valve_params(params)
    rows = []
    for i, entry in enumerate(selected):
        try:
            mod = Modulator.from_mapping(entry)
        except ValueError as exc:
            raise ValueError(f"selected[{i}]: {exc}") from None
        dead, sat = thresholds(mod.kind, p, **mod.settings)
        rows.append(
            {
                "modulator": mod.kind,
                "settings": " ".join(f"{k}={v:g}" for k, v in mod.settings.items()),
                "dead_zone_formula": THRESHOLD_FORMULAS[mod.kind][0],
                "dead_zone": float(dead),
                "saturation_formula": THRESHOLD_FORMULAS[mod.kind][1],
                "saturation": float(sat),
            }
        )
    return pd.DataFrame(rows)
