"""``params.yaml``'s ``laws:`` record: the paper's laws or the actuator's own, with the
fit's held-out FITs, covariance and bands (docs/model.md, "The general two-mode model").

:func:`laws_record` runs the choice of :func:`spa.identification.laws_fit.choose_laws` on a
refinement's runs, skips the fit where the paper's laws already come within the noise
ceiling's headroom, and writes down what was chosen and why.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from spa.identification.laws_bands import law_bands
from spa.identification.laws_fit import choose_laws
from spa.identification.refine import RefineRun
from spa.model.params import ValveParams

__all__ = ["laws_record"]


#: Held-out FIT points the identified laws must gain (choose_laws's rule): where the
#: paper's laws already come this close to the noise ceiling on every modulated
#: run, no laws can gain them, and nothing is fitted.
_LAW_HEADROOM = 2.0


def laws_record(
    prepared: Sequence[RefineRun],
    ref: Any,
    chosen: str,
    setting: str,
    held_delays: Mapping[str, tuple[float, float]] | None = None,
) -> tuple[dict[str, Any], ValveParams | None]:
    """``params.yaml``'s ``laws:`` record and, when the identified laws are chosen, the
    valve that carries them (None otherwise).

    Parameters
    ----------
    prepared : sequence of RefineRun
        Every run with the command.
    ref : RefineFit
        The chosen convention's refinement (paper's laws): its valve, held-out FITs and
        noise ceilings.
    chosen : str
        The delay convention.
    setting : {"auto", "paper"}
        ``identification.laws``.
    held_delays : mapping, optional
        The delays read at the command edges, which the refinement held: the laws' fit
        holds them too.

    Returns
    -------
    record : dict
        ``chosen``, ``setting``, ``reason`` and, when the laws were fitted, ``gain``, ``se``,
        the held-out FITs of both (``fit_paper``, ``fit_identified``), the in-sample
        ``fit_insample``, ``valve`` (``k2`` and the delays fitted with the laws),
        ``coefficients`` and ``covariance`` (``names``, ``matrix``), the laws' simultaneous
        95 % ``bands`` on a pressure grid and the pressures each mode ``visited``
        (:func:`spa.identification.laws_bands.law_bands`).
    valve : ValveParams or None
        The valve with the identified laws, when they are chosen.
    """
    modulated = [r for r in prepared if r.modulator]
    record: dict[str, Any] = {"chosen": "paper", "setting": setting}
    if setting == "paper":
        record["reason"] = "identification.laws: paper"
        return record, None
    if len(modulated) < 2:
        record["reason"] = (
            f"{len(modulated)} modulated run(s): too few to compare the laws held out; the "
            "paper's are kept"
        )
        return record, None
    room = {
        r.rid: float(ref.noise_ceiling.get(r.rid, math.nan)) - float(ref.fit_heldout[r.rid])
        for r in modulated
    }
    finite = [v for v in room.values() if math.isfinite(v)]
    if finite and max(finite) < _LAW_HEADROOM:
        record["reason"] = (
            f"the paper's laws predict every modulated run held out within "
            f"{max(finite):.1f} points of what the sensor noise allows: no laws can gain "
            f"{_LAW_HEADROOM:g} points, so none were fitted"
        )
        return record, None
    choice = choose_laws(
        prepared, ref.params, paper_heldout=ref.fit_heldout, delay=chosen, held_delays=held_delays
    )
    fit = choice.fit
    bands = law_bands(prepared, fit, delay=chosen)
    record.update(
        {
            "chosen": choice.laws,
            "reason": f"the actuator's own laws: {choice.reason}",
            "gain": _finite(choice.gain),
            "se": _finite(choice.se),
            "fit_paper": {k: round(float(v), 3) for k, v in choice.fit_paper.items()},
            "fit_identified": {k: round(float(v), 3) for k, v in choice.fit_identified.items()},
            "fit_insample": {k: round(float(v), 3) for k, v in fit.fit.items()},
            "valve": {
                "k2": float(fit.params.k2),
                "t_on": float(fit.params.t_on),
                "t_off": float(fit.params.t_off),
            },
            "coefficients": fit.laws.as_dict(),
            "covariance": {
                "names": list(fit.names),
                "matrix": [[float(v) for v in row] for row in fit.cov],
            },
            "bands": bands.to_dict(),
            "visited": bands.visited_dict(),
        }
    )
    return record, (choice.params if choice.laws == "identified" else None)


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None
