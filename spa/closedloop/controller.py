"""The controller of the closed loop: a PI with optional gain schedule and feed-forward.

One frozen value type covers P (``ki = 0``), PI, gain-scheduled PI (``kp``, ``ki`` given at
several set-points and interpolated linearly in the set-point) and any of them with the
averaged model's feed-forward ``xi_ff(r)``; the compiled loop runs the same code for all.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["PIController"]


def _floats(name: str, values: Any) -> tuple[float, ...]:
    arr = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if arr.ndim != 1 or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise ValueError(f"PIController.{name} must be finite numbers, got {values!r}")
    return tuple(float(v) for v in arr)


def _increasing(name: str, grid: tuple[float, ...]) -> None:
    if any(b <= a for a, b in itertools.pairwise(grid)):
        raise ValueError(f"PIController.{name} must be strictly increasing, got {grid}")


@dataclass(frozen=True)
class PIController:
    """A PI on the pressure error with conditional integration (docs/model.md section 8).

    Parameters
    ----------
    kp : float or sequence of float
        Proportional gain, 1/bar (input fraction per bar of error); one value, or one per
        entry of ``schedule``.
    ki : float or sequence of float
        Integral gain, 1/(bar·s); as ``kp``.
    schedule : sequence of float, optional
        Set-points (bar, strictly increasing) at which ``kp`` and ``ki`` are given; between
        them the gains are interpolated linearly in the set-point, outside they are held.
    feedforward : (sequence, sequence), optional
        ``(r, xi)``: the feed-forward input fraction at set-points ``r`` (strictly
        increasing), interpolated like the gains; ``xi`` in [0, 1].

    Raises
    ------
    ValueError
        For non-finite or negative gains, a schedule that does not increase or whose length
        differs from the gains', or a feed-forward outside [0, 1].

    Examples
    --------
    >>> PIController(kp=1.2, ki=2.0).gains(0.3)
    (1.2, 2.0, 0.0)
    >>> c = PIController(kp=(1.0, 3.0), ki=(2.0, 4.0), schedule=(0.1, 0.5))
    >>> c.gains(0.3)
    (2.0, 3.0, 0.0)
    """

    kp: float | tuple[float, ...]
    ki: float | tuple[float, ...] = 0.0
    schedule: tuple[float, ...] = ()
    feedforward: tuple[tuple[float, ...], tuple[float, ...]] | None = None

    def __post_init__(self) -> None:
        kp, ki = _floats("kp", self.kp), _floats("ki", self.ki)
        if any(v < 0.0 for v in kp + ki):
            raise ValueError(f"PIController gains must be >= 0, got kp={kp}, ki={ki}")
        schedule = _floats("schedule", self.schedule) if len(self.schedule) else ()
        _increasing("schedule", schedule)
        n = max(len(kp), len(ki))
        if schedule and n == 1:
            kp, ki = kp * len(schedule), ki * len(schedule)
        elif len(kp) == 1 and len(ki) > 1:
            kp = kp * len(ki)
        elif len(ki) == 1 and len(kp) > 1:
            ki = ki * len(kp)
        if len(kp) > 1 and len(schedule) != len(kp):
            raise ValueError(
                f"PIController: {len(kp)} gains need a schedule of {len(kp)} set-points, "
                f"got {len(schedule)}"
            )
        ff = None
        if self.feedforward is not None:
            r, xi = (_floats("feedforward", v) for v in self.feedforward)
            _increasing("feedforward set-points", r)
            if len(r) != len(xi) or any(not 0.0 <= v <= 1.0 for v in xi):
                raise ValueError(
                    "PIController.feedforward must be (r, xi) of equal length with xi in [0, 1]"
                )
            ff = (r, xi)
        object.__setattr__(self, "kp", kp[0] if len(kp) == 1 else kp)
        object.__setattr__(self, "ki", ki[0] if len(ki) == 1 else ki)
        object.__setattr__(self, "schedule", schedule)
        object.__setattr__(self, "feedforward", ff)

    @property
    def scheduled(self) -> bool:
        """True when the gains vary with the set-point."""
        return isinstance(self.kp, tuple)

    def arrays(self) -> tuple[np.ndarray, ...]:
        """``(grid, kp, ki, ff_r, ff_xi)`` as float64 arrays for the compiled loop.

        A fixed PI has a grid of one point; no feed-forward is the curve ``0`` at ``r = 0``.
        """
        kp = np.atleast_1d(np.asarray(self.kp, dtype=np.float64))
        ki = np.atleast_1d(np.asarray(self.ki, dtype=np.float64))
        grid = np.asarray(self.schedule if self.scheduled else (0.0,), dtype=np.float64)
        r, xi = self.feedforward if self.feedforward is not None else ((0.0,), (0.0,))
        return grid, kp, ki, np.asarray(r, np.float64), np.asarray(xi, np.float64)

    def scaled(self, factor: float) -> PIController:
        """The same PI with ``kp`` and ``ki`` times ``factor`` (schedule and feed-forward
        unchanged): the loop this PI closes on a plant ``factor`` times steeper.

        Examples
        --------
        >>> PIController(kp=1.0, ki=2.0).scaled(1.5).gains(0.3)
        (1.5, 3.0, 0.0)
        """

        def times(v: float | tuple[float, ...]) -> float | tuple[float, ...]:
            return tuple(factor * x for x in v) if isinstance(v, tuple) else factor * v

        return PIController(
            kp=times(self.kp),
            ki=times(self.ki),
            schedule=self.schedule,
            feedforward=self.feedforward,
        )

    def gains(self, r: float) -> tuple[float, float, float]:
        """``(kp, ki, xi_ff)`` at set-point ``r`` (as the loop interpolates them)."""
        grid, kp, ki, fr, fx = self.arrays()
        return interp(r, grid, kp), interp(r, grid, ki), interp(r, fr, fx)

    def to_mapping(self) -> dict[str, Any]:
        """Plain mapping (YAML-ready): gains, schedule and feed-forward as lists."""
        out: dict[str, Any] = {"kp": self.kp, "ki": self.ki}
        if self.scheduled:
            out = {"kp": list(self.kp), "ki": list(self.ki), "schedule": list(self.schedule)}  # type: ignore[arg-type]
        if self.feedforward is not None:
            out["feedforward"] = {"r": list(self.feedforward[0]), "xi": list(self.feedforward[1])}
        return out

    @classmethod
    def from_mapping(cls, mapping: dict[str, Any]) -> PIController:
        """Inverse of :meth:`to_mapping`."""
        ff = mapping.get("feedforward")
        return cls(
            kp=mapping["kp"],
            ki=mapping.get("ki", 0.0),
            schedule=tuple(mapping.get("schedule", ())),
            feedforward=None if ff is None else (tuple(ff["r"]), tuple(ff["xi"])),
        )


def interp(x: float, xp: Sequence[float] | np.ndarray, fp: Sequence[float] | np.ndarray) -> float:
    """Linear interpolation held constant outside ``xp`` (the compiled loop's formula).

    Exact at the nodes: ``interp(xp[i], xp, fp) == fp[i]``.

    Examples
    --------
    >>> interp(0.25, [0.0, 1.0], [1.0, 3.0]), interp(2.0, [0.0, 1.0], [1.0, 3.0])
    (1.5, 3.0)
    """
    n = len(xp)
    if n == 1 or x <= xp[0]:
        return float(fp[0])
    if x >= xp[n - 1]:
        return float(fp[n - 1])
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    return float(fp[lo] + (x - xp[lo]) * (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]))
