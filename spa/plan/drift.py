"""Which drifts a verification's predictions can detect.

A prediction worth checking is one that a changed plant breaks. For every staircase and
sine a verification predicts (:func:`spa.plan.verify.staircase_predictions`,
:func:`spa.plan.verify.sine_predictions`), the identified valve is drifted by each of
:data:`DRIFTS` (one parameter at a time, ±50 %), the drifted valve's noiseless response is
predicted as the verification measures it, and the prediction counts as broken by that
drift when the drifted value leaves the band. A prediction kind that no drift breaks cannot
fail on the bench: the plan says so (``verify.drift_check`` in ``plan.yaml``) rather than
count its "kept" as evidence.

The drifted response carries no sensor noise and no model error, so this is what each drift
moves the prediction by, not the chance that one recording shows it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

from spa.model.params import ValveParams

__all__ = ["DRIFTS", "drift_check", "drifted", "unbroken"]

#: The drifts checked: each parameter times each factor, the others as identified.
DRIFTS: dict[str, tuple[float, ...]] = {
    "t_on": (0.5, 1.5),
    "t_off": (0.5, 1.5),
    "k2": (0.5, 1.5),
    "tau2": (0.5, 1.5),
}

#: Each prediction kind: its value's key in a staircase's or a sine's prediction, and the keys
#: of its band.
KINDS: dict[str, tuple[str, str, str]] = {
    "level": ("p", "lo", "hi"),
    "fit": ("fit", "fit_lo", "fit_hi"),
    "sine_mean": ("mean", "mean_lo", "mean_hi"),
    "sine_amplitude": ("amplitude", "amplitude_lo", "amplitude_hi"),
}


def drifted(params: ValveParams, name: str, factor: float) -> ValveParams | None:
    """``params`` with ``name`` times ``factor``; None when that valve is not a valid one.

    Examples
    --------
    >>> drifted(ValveParams(), "tau2", 1.5).tau2 == 1.5 * ValveParams().tau2
    True
    """
    try:
        return dataclasses.replace(params, **{name: getattr(params, name) * factor})
    except (TypeError, ValueError):
        return None


def _outside(value: Any, lo: Any, hi: Any) -> bool:
    values = value if isinstance(value, list) else [value]
    los = lo if isinstance(lo, list) else [lo] * len(values)
    his = hi if isinstance(hi, list) else [hi] * len(values)
    return any(not (a <= v <= b) for v, a, b in zip(values, los, his, strict=True))


def drift_check(
    predictions: Mapping[str, Mapping[str, Any]],
    predict: Callable[[str, ValveParams], Mapping[str, Any]],
    params: ValveParams,
    drifts: Mapping[str, tuple[float, ...]] = DRIFTS,
) -> dict[str, dict[str, Any]]:
    """For each prediction kind, the drifts that move some prediction out of its band.

    Parameters
    ----------
    predictions : mapping
        Run id -> the run's predictions (a staircase's or a sine's, with their bands).
    predict : callable
        ``(run id, valve) -> predictions`` of that run on that valve, without model error
        (only the values are read).
    params : ValveParams
        The identified valve.
    drifts : mapping, default :data:`DRIFTS`
        Parameter -> factors.

    Returns
    -------
    dict
        Kind (``level``, ``fit``, ``sine_mean``, ``sine_amplitude``; those the predictions
        have) -> ``broken_by`` (the drifts, e.g. ``"tau2 x1.5"``, that break at least one
        prediction of that kind) and ``can_fail`` (whether any does).

    Examples
    --------
    >>> bands = {"s": {"p": [0.5], "lo": [0.4], "hi": [0.6], "fit": 99, "fit_lo": 0, "fit_hi": 100}}
    >>> out = drift_check(bands, lambda rid, v: {"p": [0.5 * v.tau2 / 0.826], "fit": 99},
    ...                   ValveParams(), {"tau2": (0.5, 1.5)})
    >>> out["level"], out["fit"]["can_fail"]
    ({'broken_by': ['tau2 x0.5', 'tau2 x1.5'], 'can_fail': True}, False)
    """
    kinds = [k for k, (v, _, _) in KINDS.items() if any(v in p for p in predictions.values())]
    broken: dict[str, list[str]] = {k: [] for k in kinds}
    for name, factors in drifts.items():
        for factor in factors:
            valve = drifted(params, name, factor)
            if valve is None:
                continue
            label = f"{name} x{factor:g}"
            for rid, pred in predictions.items():
                moved = predict(rid, valve)
                for kind in kinds:
                    key, lo, hi = KINDS[kind]
                    if key in pred and label not in broken[kind]:
                        if _outside(moved[key], pred[lo], pred[hi]):
                            broken[kind].append(label)
    return {k: {"broken_by": v, "can_fail": bool(v)} for k, v in broken.items()}


def unbroken(
    predictions: Mapping[str, Mapping[str, Any]],
    predict: Callable[[str, ValveParams], Mapping[str, Any]],
    params: ValveParams,
    drifts: Mapping[str, tuple[float, ...]] = DRIFTS,
) -> dict[str, dict[str, Any]]:
    """The predictions no drift of :data:`DRIFTS` moves out of its band, run by run: a
    staircase's ``level`` (the indices of its levels) and ``fit`` (True when unbroken), a
    sine's ``mean`` and ``amplitude``. A verification drops them: their "kept" is no
    evidence (a level at xi = 0 is 0 bar on any valve).

    Examples
    --------
    >>> bands = {"s": {"p": [0.0, 0.5], "lo": [-0.01, 0.4], "hi": [0.01, 0.6], "fit": 99,
    ...                "fit_lo": 0, "fit_hi": 100}}
    >>> moved = lambda rid, v: {"p": [0.0, 0.5 * v.tau2 / 0.826], "fit": 99}
    >>> unbroken(bands, moved, ValveParams(), {"tau2": (0.5, 1.5)})
    {'s': {'level': [0], 'fit': True}}
    """
    flags: dict[str, dict[str, Any]] = {}
    for rid, pred in predictions.items():
        if "p" in pred:
            flags[rid] = {"level": [True] * len(pred["p"]), "fit": True}
        else:
            flags[rid] = {"mean": True, "amplitude": True}
    for name, factors in drifts.items():
        for factor in factors:
            valve = drifted(params, name, factor)
            if valve is None:
                continue
            for rid, pred in predictions.items():
                moved = predict(rid, valve)
                f = flags[rid]
                if "level" in f:
                    for i, (v, a, b) in enumerate(
                        zip(moved["p"], pred["lo"], pred["hi"], strict=True)
                    ):
                        f["level"][i] = f["level"][i] and a <= v <= b
                    f["fit"] = f["fit"] and pred["fit_lo"] <= moved["fit"] <= pred["fit_hi"]
                else:
                    for key in ("mean", "amplitude"):
                        lo, hi = pred[f"{key}_lo"], pred[f"{key}_hi"]
                        f[key] = f[key] and lo <= moved[key] <= hi
    for f in flags.values():
        if "level" in f:
            f["level"] = [i for i, ok in enumerate(f["level"]) if ok]
    return flags
