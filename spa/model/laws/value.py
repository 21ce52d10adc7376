"""The actuator's two-mode laws as one typed value (docs/model.md, "The general two-mode
model").

While the valve is open the pressure follows ``dP/dt = f_open(P) = (k2 - P)*g(P)``; while
it is closed, ``dP/dt = f_closed(P) = -P**m * h(P)``, with ``g, h > 0`` smooth and
``m`` in [1/2, 1]. The rates are written relative to the paper's constants, so that the
paper's laws (Eqs. 1–2) are the case with every coefficient zero and ``m = 1/2``::

    g(P) = exp(a(s)) / tau2,
    h(P) = sqrt(k2) * k2**(-m) * exp(b(s)) / c1,     s = P/k2 clipped to [0, 1],

``a`` and ``b`` being the polynomials through the values ``log_g`` and ``log_h`` at the
``knots`` (fractions of ``k2``). Positivity holds by construction; nothing forces the rates
to be monotone.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["DEFAULT_KNOTS", "Laws", "laws_from"]

#: Knots of the log-rate polynomials, as fractions of ``k2`` (a cubic through four values).
DEFAULT_KNOTS: tuple[float, ...] = (0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0)


def _floats(name: str, value: Any) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in np.atleast_1d(np.asarray(value, dtype=np.float64)))
    except (TypeError, ValueError):
        raise ValueError(f"Laws.{name} must be a sequence of numbers, got {value!r}") from None
    if not out or not all(math.isfinite(v) for v in out):
        raise ValueError(f"Laws.{name} must hold at least one finite number, got {value!r}")
    return out


@dataclass(frozen=True, slots=True)
class Laws:
    """Charge and discharge laws of the actuator, with the paper's as the nested case.

    Parameters
    ----------
    log_g : sequence of float
        ``log(g*tau2)`` at the knots: the charge rate relative to the paper's ``1/tau2``.
    log_h : sequence of float
        ``log(h*c1*k2**(m - 1/2))`` at the knots: the discharge rate relative to the
        paper's ``1/c1``.
    m : float, optional
        Exponent of the discharge law, in [1/2, 1] (1/2: the choked square-root law of
        Eq. 1; 1: a linear, laminar exhaust).
    knots : sequence of float, optional
        Where ``log_g`` and ``log_h`` are given, as fractions of ``k2``: strictly
        increasing, within [0, 1]. Each log-rate is the polynomial through its values
        (degree ``len(knots) - 1``) and is held constant outside [0, k2].

    Raises
    ------
    ValueError
        If a field is not finite, ``m`` is outside [1/2, 1], the knots are not strictly
        increasing within [0, 1], or ``log_g``/``log_h`` do not hold one value per knot;
        the message names the field.

    Examples
    --------
    >>> Laws().is_paper
    True
    >>> Laws(log_g=(0.0, 0.1, 0.2, 0.3), log_h=(0, 0, 0, 0), m=0.7).is_paper
    False
    """

    log_g: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    log_h: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    m: float = 0.5
    knots: tuple[float, ...] = DEFAULT_KNOTS
    _coef: tuple[np.ndarray, np.ndarray] = field(
        init=False, repr=False, compare=False, hash=False, default=(np.zeros(1), np.zeros(1))
    )

    def __post_init__(self) -> None:
        knots = _floats("knots", self.knots)
        if any(b <= a for a, b in itertools.pairwise(knots)) or not (
            0.0 <= knots[0] and knots[-1] <= 1.0
        ):
            raise ValueError(
                f"Laws.knots must be strictly increasing within [0, 1] (fractions of k2), "
                f"got {self.knots!r}"
            )
        object.__setattr__(self, "knots", knots)
        for name in ("log_g", "log_h"):
            values = _floats(name, getattr(self, name))
            if len(values) != len(knots):
                raise ValueError(
                    f"Laws.{name} must hold one value per knot ({len(knots)}), got {len(values)}"
                )
            object.__setattr__(self, name, values)
        try:
            m = float(self.m)
        except (TypeError, ValueError):
            raise ValueError(f"Laws.m must be a number in [0.5, 1], got {self.m!r}") from None
        if not 0.5 <= m <= 1.0:
            raise ValueError(f"Laws.m must be in [0.5, 1], got {self.m!r}")
        object.__setattr__(self, "m", m)
        object.__setattr__(self, "_coef", (self._poly(self.log_g), self._poly(self.log_h)))

    @property
    def is_paper(self) -> bool:
        """True for the paper's laws: constant ``g = 1/tau2``, ``h = 1/c1`` and ``m = 1/2``."""
        return self.m == 0.5 and not any(self.log_g) and not any(self.log_h)

    def as_dict(self) -> dict[str, Any]:
        """Plain ``{name: value}`` (lists of floats); ``Laws(**laws.as_dict()) == laws``."""
        return {
            "log_g": list(self.log_g),
            "log_h": list(self.log_h),
            "m": self.m,
            "knots": list(self.knots),
        }

    def _poly(self, values: tuple[float, ...]) -> np.ndarray:
        """Monomial coefficients (in ``s``) of the polynomial through ``values``."""
        s = np.asarray(self.knots)
        return np.linalg.solve(np.vander(s, increasing=True), np.asarray(values))

    def log_rates(
        self, s: npt.ArrayLike, derivative: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """``a(s)``, ``b(s)`` (or their derivatives in ``s``), ``s`` clipped to [0, 1].

        The derivative is 0 outside [0, 1], where the rates are held constant.
        """
        x = np.asarray(s, dtype=np.float64)
        inside = (x >= 0.0) & (x <= 1.0)
        x = np.clip(x, 0.0, 1.0)
        out = []
        for c in self._coef:
            if derivative:
                c = np.polynomial.polynomial.polyder(c) if c.size > 1 else np.zeros(1)
                out.append(np.where(inside, np.polynomial.polynomial.polyval(x, c), 0.0))
            else:
                out.append(np.polynomial.polynomial.polyval(x, c))
        return out[0], out[1]


def laws_from(value: Laws | Mapping[str, Any] | None) -> Laws | None:
    """A :class:`Laws`, built from its :meth:`Laws.as_dict` form when given a mapping.

    Returns None for None and for the paper's laws (they are the valve's default).

    Raises
    ------
    ValueError
        If ``value`` is neither None, a Laws nor a mapping of its fields.
    """
    if value is None:
        return None
    if isinstance(value, Mapping):
        unknown = set(value) - {"log_g", "log_h", "m", "knots"}
        if unknown:
            raise ValueError(
                f"ValveParams.laws has unknown keys {sorted(unknown)}; "
                "expected log_g, log_h, m, knots"
            )
        value = Laws(**value)
    if not isinstance(value, Laws):
        raise ValueError(
            f"ValveParams.laws must be a Laws, a mapping of its fields or None, "
            f"got {type(value).__name__}"
        )
    return None if value.is_paper else value
