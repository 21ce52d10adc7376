"""The sensor's noise the disturbance runs use, and what it is: measured, bounded or unknown.

The identification writes ``noise`` in ``params.yaml`` (``sensor``, bar, estimated where
nothing moves; ``method``; ``upper_bound``, true when it could only be bounded from second
differences; ``model_residual``, the pulse fit's residual). :func:`noise_of` reads it. The
pulse fit's residual RMS (``fits.pulse.rmse``) holds the sensor's noise and all the model
misses, so it is never reported as the sensor's noise: a ``params.yaml`` without ``noise``
(written before it existed) has an unknown sensor noise, and the disturbance run then uses the
model residual as an upper bound of it (the noise is part of the residual), and says so; with
neither, an assumed :data:`NOISE_FALLBACK`, said as assumed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["NOISE_FALLBACK", "SensorNoise", "noise_of", "sensor_noise"]

#: The sensor noise assumed when the identification gives neither a noise nor a residual,
#: bar (the simulated bench's).
NOISE_FALLBACK = 0.005

#: What a :class:`SensorNoise` value is.
SOURCES = ("measured", "upper_bound", "model_residual", "assumed", "given")


def _positive(value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return math.nan
    return v if math.isfinite(v) and v > 0.0 else math.nan


@dataclass(frozen=True)
class SensorNoise:
    """The sensor noise a disturbance run uses, bar, and where it comes from.

    Attributes
    ----------
    value : float
        The standard deviation used, bar.
    source : str
        ``"measured"`` (``params.yaml``'s ``noise.sensor``), ``"upper_bound"`` (the same,
        bounded only), ``"model_residual"`` (no ``noise``: the pulse fit's residual as an upper
        bound of an unknown noise), ``"assumed"`` (neither) or ``"given"`` (by the caller).
    method : str
        How it was estimated (``noise.method``), or ``""``.
    model_residual : float
        The pulse fit's residual RMS, bar (NaN when unknown): reported under its own name.

    Examples
    --------
    >>> SensorNoise(0.006, "measured", "still levels").words()
    'sensor noise of 6.0 mbar (still levels)'
    >>> SensorNoise(0.117, "model_residual", model_residual=0.117).words()
    'sensor noise unknown (params.yaml has no noise estimate): the model residual of 117.0 mbar, an upper bound of it,'
    """  # noqa: E501

    value: float
    source: str = "given"
    method: str = ""
    model_residual: float = math.nan

    @property
    def bound(self) -> bool:
        """Whether ``value`` is only an upper bound of the sensor's noise (or assumed)."""
        return self.source in ("upper_bound", "model_residual")

    def words(self) -> str:
        """The noise as the subject of the disturbance sentence ("... adds X mbar RMS")."""
        mbar = f"{self.value * 1e3:.1f} mbar"
        how = f" ({self.method})" if self.method else ""
        if self.source == "upper_bound":
            method = f", {self.method}" if self.method else ""
            return f"sensor noise of at most {mbar} (an upper bound{method})"
        if self.source == "model_residual":
            return (
                "sensor noise unknown (params.yaml has no noise estimate): the model residual "
                f"of {mbar}, an upper bound of it,"
            )
        if self.source == "assumed":
            return f"sensor noise unknown: an assumed {mbar}"
        return f"sensor noise of {mbar}{how}"

    def to_mapping(self) -> dict[str, Any]:
        """``controllers.yaml``'s ``bench.sensor_noise``: value, source, method, residual."""
        residual = self.model_residual if math.isfinite(self.model_residual) else None
        return {
            "value": float(self.value),
            "source": self.source,
            "method": self.method,
            "model_residual": residual,
        }


def noise_of(identified: Mapping[str, Any] | None) -> SensorNoise:
    """The sensor noise of ``params.yaml``'s content, and what it is.

    Parameters
    ----------
    identified : mapping or None
        ``params.yaml``'s content: its ``noise`` mapping (``sensor``, ``method``,
        ``upper_bound``, ``model_residual``) when present; else its ``fits.pulse.rmse``, the
        model residual, as an upper bound of an unknown noise.

    Returns
    -------
    SensorNoise

    Examples
    --------
    >>> noise_of({"noise": {"sensor": 0.006, "method": "still", "upper_bound": False},
    ...           "fits": {"pulse": {"rmse": 0.117}}}).value
    0.006
    >>> n = noise_of({"fits": {"pulse": {"rmse": 0.117}}})
    >>> n.source, n.value
    ('model_residual', 0.117)
    >>> noise_of(None).source
    'assumed'
    """
    found = dict(identified or {})
    fits = found.get("fits")
    pulse = fits.get("pulse") if isinstance(fits, Mapping) else None
    residual = _positive(pulse.get("rmse") if isinstance(pulse, Mapping) else None)
    noise = found.get("noise")
    if isinstance(noise, Mapping):
        own = _positive(noise.get("model_residual"))
        residual = own if math.isfinite(own) else residual
        sensor = _positive(noise.get("sensor"))
        if math.isfinite(sensor):
            source = "upper_bound" if bool(noise.get("upper_bound", False)) else "measured"
            return SensorNoise(sensor, source, str(noise.get("method") or ""), residual)
    if math.isfinite(residual):
        return SensorNoise(residual, "model_residual", "", residual)
    return SensorNoise(NOISE_FALLBACK, "assumed")


def sensor_noise(identified: Mapping[str, Any] | None) -> SensorNoise:
    """The sensor noise of ``params.yaml``'s content (:func:`noise_of`)."""
    return noise_of(identified)
