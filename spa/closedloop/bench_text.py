"""The chosen loop's promise, margins, verdict and disturbances in one sentence
(:func:`bench_sentence`, for :func:`spa.closedloop.bench.bench_outputs`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from spa._checks import float_or_nan as _num
from spa.closedloop.choice import MAX_OVERSHOOT
from spa.closedloop.disturbance import DROP
from spa.model.params import ValveParams

__all__ = ["WIDE_LAW", "bench_sentence", "laws_envelope", "laws_record_clause"]


def bench_sentence(summary: Mapping[str, Any]) -> str:
    """The chosen loop's promise, margins, verdict and disturbances, in words; never a NaN.

    Examples
    --------
    >>> s = bench_sentence({"n_corners": 32, "tau_c": 0.2, "worst_rise_time": None,
    ...   "worst_overshoot": 14.0, "tau_c_robust": None, "drop_level": 0.35,
    ...   "recovery_time": None, "dip": 0.01, "noise": 0.005, "added_ripple_rms": 0.002})
    >>> "nan" in s, "does not reach 90 %" in s
    (False, True)
    """

    def num(key: str) -> float:
        return _num(summary.get(key))

    limit = num("max_overshoot")
    if not math.isfinite(limit):
        limit = MAX_OVERSHOOT
    corners = num("n_corners")
    n = int(corners) if math.isfinite(corners) else 0
    over, rise = num("worst_overshoot"), num("worst_rise_time")
    where = f"Over the identification's 95 % box ({n} corners)"
    if summary.get("model_error"):
        where += " merged with the model error measured on this dataset"
    rise_text = (
        f"its worst rise time is {rise:.2f} s" if math.isfinite(rise) else
        "a step of one of its plants does not reach 90 %"
    )  # fmt: skip
    over_text = f"overshoot {over:.0f} %" if math.isfinite(over) else "overshoot unknown"
    text = f"{where} at τ_c = {num('tau_c'):.3g} s, {rise_text} and {over_text}"
    promise = summary.get("promise") or {}
    if promise.get("kept"):
        tau, hold = _num(promise.get("tau_c")), _num(promise.get("hold"))
        settle, ripple = _num(promise.get("settling_time")), _num(promise.get("ripple_pp"))
        below = summary.get("below") or {}
        lowest = _num(below.get("lowest")) if isinstance(below, Mapping) else math.nan
        scope = f" for set-points from {lowest:.3g} bar up" if math.isfinite(lowest) else ""
        text += (
            f". Promise (the header, τ_c = {tau:.3g} s){scope}: on any plant within that box, "
            f"overshoot ≤ {_num(promise.get('overshoot')):.0f} % and every level within 2 % of "
            f"its step by the end of a {hold:.1f} s hold"
        )
        if math.isfinite(settle):
            text += f", settling (2 %) ≤ {settle:.2f} s"
        elif math.isfinite(ripple):
            text += ", though its cycle-mean pressure does not stay within 2 % on every level"
        if math.isfinite(ripple):
            text += f", ripple ≤ {ripple * 1e3:.0f} mbar peak-to-peak"
        if math.isfinite(lowest):
            text += below_clause(lowest, below.get("laws_envelope"))
    elif promise:
        text += (
            f". No promise: no τ_c tried keeps the overshoot within {limit:.3g} % with every "
            "level settled on every plant of the box"
        )
        text += laws_record_clause(summary.get("laws_envelope"))
    unresolved = summary.get("unresolved_delays") or {}
    if isinstance(unresolved, Mapping) and unresolved.get("sentence"):
        text += ". " + str(unresolved["sentence"]).rstrip(".")
    margins = summary.get("margins") or {}
    gm, dm = _num(margins.get("gain_margin")), _num(margins.get("delay_margin"))
    if math.isfinite(gm) or math.isfinite(dm):
        parts = []
        if math.isfinite(gm):
            parts.append(f"gain margin {gm:.2g}")
        if math.isfinite(dm):
            parts.append(f"delay margin {dm * 1e3:.0f} ms")
        text += f"; {' and '.join(parts)} on the averaged model"
    clause = str(summary.get("adequacy_clause") or "")
    if "verified" in summary:
        if summary.get("verified"):
            text += ". Controller verified" + (f" ({clause})" if clause else "")
        else:
            text += ". Controller unverified" + (f": {clause}" if clause else "")
    rec = num("recovery_time")
    if math.isnan(rec):
        back = "is not back within 2 % before the level ends"
    elif rec == 0.0:
        back = "stays within 2 % of the undisturbed run"
    else:
        back = f"is back within 2 % after {rec:.2f} s"
    dip, noise, added = num("dip"), num("noise"), num("added_ripple_rms")
    tail = f". After a {DROP * 100:.0f} % supply drop"
    if math.isfinite(num("drop_level")):
        tail += f" at {num('drop_level'):.2f} bar"
    tail += f" the pressure dips {dip * 1e3:.0f} mbar and {back}" if math.isfinite(dip) else (
        f" the pressure {back}"
    )  # fmt: skip
    if math.isfinite(noise) and math.isfinite(added):
        tail += "; " + _noise_words(summary, noise, added)
    return f"{text}{tail}. The C header is closed_loop/controller.h."


def _noise_words(summary: Mapping[str, Any], noise: float, added: float) -> str:
    """The sensor noise's clause: measured, an upper bound or unknown (``sensor_noise`` of
    the summary, :meth:`spa.closedloop.noise.SensorNoise.to_mapping`), and the model residual
    under its own name.

    Examples
    --------
    >>> _noise_words({}, 0.005, 0.001)
    'sensor noise of 5.0 mbar adds 1.00 mbar RMS ripple'
    >>> _noise_words({"sensor_noise": {"value": 0.006, "source": "measured", "method": "still"
    ...     " levels", "model_residual": 0.117}}, 0.006, 0.001)
    'sensor noise of 6.0 mbar (still levels) adds 1.00 mbar RMS ripple (the model residual of the pulse fit, 117.0 mbar, is the model error and the noise together)'
    >>> _noise_words({}, 0.005, -0.00004)
    'sensor noise of 5.0 mbar adds no RMS ripple (its median change is -0.04 mbar)'
    """  # noqa: E501
    from spa.closedloop.noise import SensorNoise

    given = summary.get("sensor_noise")
    given = given if isinstance(given, Mapping) else {}
    residual = _num(given.get("model_residual"))
    said = SensorNoise(noise, str(given.get("source") or "given"), str(given.get("method") or ""))
    verb = "adds at most" if said.bound else "adds"
    text = f"{said.words()} {verb} {added * 1e3:.2f} mbar RMS ripple"
    if added < 0.0:  # the noise moved the loop's own limit cycle the other way
        text = f"{said.words()} adds no RMS ripple (its median change is {added * 1e3:.2f} mbar)"
    if math.isfinite(residual) and said.source != "model_residual":
        text += (
            f" (the model residual of the pulse fit, {residual * 1e3:.1f} mbar, is the model "
            "error and the noise together)"
        )
    return text


#: A law's band wider than this factor either way is named when no promise holds.
WIDE_LAW = 1.5


def laws_envelope(
    params: ValveParams, intervals: Mapping[str, tuple[float, float]] | None
) -> dict[str, float]:
    """How far the box moves each of a laws valve's two laws, as a factor either way.

    The laws' box scales the charge law through ``tau2`` and the exhaust law through ``c1``
    (:func:`spa.identification.identified.laws_intervals`); the factor is the larger of
    ``hi/x`` and ``x/lo``.

    Examples
    --------
    >>> from spa.model.laws import Laws
    >>> v = ValveParams(tau2=1.0, c1=0.5, laws=Laws(log_g=(0, .3), log_h=(0, 0), knots=(0, 1)))
    >>> laws_envelope(v, {"tau2": (0.8, 1.25), "c1": (0.2, 1.4)})
    {'charge': 1.25, 'exhaust': 2.8}
    >>> laws_envelope(ValveParams(), {"c1": (0.2, 1.4)})
    {}
    """
    if params.laws is None or not intervals:
        return {}
    out = {}
    for name, law in (("tau2", "charge"), ("c1", "exhaust")):
        if name in intervals:
            lo, hi = (float(v) for v in intervals[name])
            x = float(getattr(params, name))
            if lo > 0.0 and x > 0.0:
                out[law] = round(max(hi / x, x / lo), 6)
    return out


def _widest_law(envelope: Mapping[str, float] | None) -> tuple[str, float, str] | None:
    """The law whose band is widest, its factor and the runs that narrow it, when it moves
    by more than :data:`WIDE_LAW` either way (None otherwise)."""
    if not envelope:
        return None
    law, factor = max(envelope.items(), key=lambda kv: kv[1])
    if not factor > WIDE_LAW:
        return None
    return law, factor, "discharges" if law == "exhaust" else "charges"


def laws_record_clause(envelope: Mapping[str, float] | None) -> str:
    """What to record when a laws valve's box breaks every promise: the law whose band is
    widest, when it moves by more than :data:`WIDE_LAW` either way ("" otherwise).

    Examples
    --------
    >>> laws_record_clause({"charge": 1.2, "exhaust": 2.8})[:60]
    '. The exhaust law is the widest part of the box (its 95 % ba'
    >>> laws_record_clause({"charge": 1.2, "exhaust": 1.3})
    ''
    """
    widest = _widest_law(envelope)
    if widest is None:
        return ""
    law, factor, runs = widest
    return (
        f". The {law} law is the widest part of the box (its 95 % band spans ×{factor:.2g} "
        f"either way over the pressures recorded): more {runs}, through the set-points' "
        "range, narrow it (spa plan --replicates)"
    )


def below_clause(lowest: float, envelope: Mapping[str, float] | None) -> str:
    """Why a laws valve's promise leaves out the set-points below ``lowest`` bar, and what
    to record to cover them.

    Examples
    --------
    >>> s = below_clause(0.57, {"charge": 1.2, "exhaust": 4.3})
    >>> "exhaust law's 95 % band spans ×4.3" in s, "more discharges below 0.57 bar" in s
    (True, True)
    >>> below_clause(0.57, {"charge": 1.2, "exhaust": 1.3}).endswith("every plant of the box")
    True
    """
    head = f". Below {lowest:.3g} bar no τ_c tried keeps it on every plant of the box"
    widest = _widest_law(envelope)
    if widest is None:
        return head
    law, factor, runs = widest
    return (
        f"{head}: the {law} law's 95 % band spans ×{factor:.2g} either way over all the "
        f"pressures recorded; more {runs} below {lowest:.3g} bar narrow it "
        "(spa plan --replicates)"
    )
