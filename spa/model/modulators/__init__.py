"""Digital pulse modulators: one module per kind, a registry, and the value type.

=================  ===========================================================
module             holds
=================  ===========================================================
``base``           :class:`ModulatorKind` (the interface) and the registry
``core``           :class:`Modulator` (the value), :func:`modulate`, checks
``pwm``            PWM (``f_w``)
``ipfm``           IPFM (``t_h``, ``gain``)
``iipfm``          inverse IPFM (``t_l``, ``gain``)
``dsm``            first-order ΔΣ (``period``)
``lpwm``           model-inverse PWM (``f_w`` and the valve it inverts)
=================  ===========================================================

A new kind is one module defining a :class:`ModulatorKind` subclass and one line
``register(MyKind)``; nothing outside this package names a kind.
"""

from __future__ import annotations

# The names imported here and left out of __all__ stay importable for the code that uses them.
# ruff: noqa: F401
from spa.model.modulators.base import REGISTRY, ModulatorKind, get_kind, kinds, register
from spa.model.modulators.core import (
    MODULATOR_ORDER,
    MODULATORS,
    PARAMETER,
    Modulator,
    check_settings,
    modulate,
    parse_modulator,
)
from spa.model.modulators.dsm import DSM
from spa.model.modulators.iipfm import IIPFM
from spa.model.modulators.ipfm import IPFM
from spa.model.modulators.lpwm import LPWM
from spa.model.modulators.pwm import PWM

__all__ = [
    "DSM",
    "IIPFM",
    "IPFM",
    "LPWM",
    "MODULATORS",
    "PWM",
    "Modulator",
    "ModulatorKind",
    "check_settings",
    "get_kind",
    "kinds",
    "modulate",
    "parse_modulator",
    "register",
]

for _kind in (PWM, IPFM, IIPFM, DSM, LPWM):
    register(_kind)
