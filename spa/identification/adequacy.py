"""Model adequacy: how well the refined model predicts runs it was not fitted to, per modulator,
beside what the sensor noise alone allows (docs/explanation/identification.md)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from spa._checks import float_or_nan as _num

__all__ = ["Adequacy", "adequacy_clause", "assess"]


def _median(values: Sequence[float]) -> float:
    vals = [v for v in values if math.isfinite(v)]
    return float(np.median(vals)) if vals else math.nan


@dataclass(frozen=True)
class Adequacy:
    """Whether the identified model describes the valve well enough for its use.

    Attributes
    ----------
    threshold : float
        Required held-out FIT, % of the noise ceiling.
    noise_ceiling_fit : float
        Median FIT % a perfect model would reach on the runs' cycle means (sensor noise only).
    heldout_median, insample_median : float
        Median leave-one-run-out and in-sample FIT % of the cycle means.
    heldout_per_modulator, insample_per_modulator : mapping
        The same medians per modulator type.
    worst_run : str
        Run with the lowest held-out FIT (``""`` when none).
    worst_fit : float
        Its held-out FIT %.
    adequate : bool
        Held-out median (and every modulator's) at least ``threshold`` % of the ceiling.
    measured_modulators : tuple of str
        Modulator types run on this bench.
    sentence : str
        The verdict in words.
    heldout_runs : tuple of str
        The runs each left out in turn and predicted from the others' parameters.
    modulated_assessed : bool
        Whether modulated runs were among them: without, the verdict is about the runs the
        valve was identified from (repeats of its experiments), not about modulated use.
    checks_passed : bool
        The residuals are white and the repeats agree (:mod:`spa.identification.diagnostics`).
    """

    threshold: float = 80.0
    noise_ceiling_fit: float = math.nan
    heldout_median: float = math.nan
    insample_median: float = math.nan
    heldout_per_modulator: Mapping[str, float] = field(default_factory=dict)
    insample_per_modulator: Mapping[str, float] = field(default_factory=dict)
    worst_run: str = ""
    worst_fit: float = math.nan
    adequate: bool = True
    measured_modulators: tuple[str, ...] = ()
    sentence: str = ""
    heldout_runs: tuple[str, ...] = ()
    modulated_assessed: bool = True
    checks_passed: bool = True

    def with_checks(self, checks: Mapping[str, Any]) -> Adequacy:
        """This verdict with the statistical checks of :func:`spa.identification.refined`
        added: repeats of one experiment that disagree make the model inadequate (it cannot
        describe all of them); residuals that are not white are named, not judged (real
        benches rarely give white residuals at a fine step)."""
        sentences = list(checks.get("sentences") or ())
        repeats_ok = bool(checks.get("repeats_agree", True))
        adequate = self.adequate and repeats_ok
        sentence = self.sentence
        if sentences:
            sentence = f"{sentence} Checks: " + "; ".join(sentences) + "."
        return replace(
            self,
            adequate=adequate,
            sentence=sentence,
            checks_passed=repeats_ok and bool(checks.get("white", True)),
        )

    @property
    def required_fit(self) -> float:
        """The held-out FIT % the threshold asks for (``threshold`` % of the ceiling)."""
        ceiling = self.noise_ceiling_fit if math.isfinite(self.noise_ceiling_fit) else 100.0
        return self.threshold / 100.0 * ceiling

    def modulator_adequate(self, modulator_type: str) -> bool:
        """Whether the model describes ``modulator_type``'s runs: its held-out median over all
        runs and over that modulator's runs reach the required FIT.

        A loop or a setting of one modulator is judged on that modulator's runs (and the
        dataset's median), not on another modulator's: ``adequate`` (every modulator) is the
        dataset's verdict, this one the setting's.
        """
        fit = _num(self.heldout_per_modulator.get(modulator_type, math.nan))
        if not math.isfinite(fit):
            return self.adequate
        overall = self.heldout_median
        return (not math.isfinite(overall) or overall >= self.required_fit) and (
            fit >= self.required_fit
        )

    @classmethod
    def from_mapping(cls, m: Mapping[str, Any] | None) -> Adequacy:
        """From the ``adequacy:`` mapping of ``params.yaml`` (missing keys: defaults)."""
        m = m or {}
        held = m.get("heldout_fit") or {}
        ins = m.get("insample_fit") or {}
        worst = m.get("worst_run") or {}
        return cls(
            threshold=_num(m.get("threshold", 80.0)),
            noise_ceiling_fit=_num(m.get("noise_ceiling_fit")),
            heldout_median=_num(held.get("median")),
            insample_median=_num(ins.get("median")),
            heldout_per_modulator={
                str(k): _num(v) for k, v in (held.get("per_modulator") or {}).items()
            },
            insample_per_modulator={
                str(k): _num(v) for k, v in (ins.get("per_modulator") or {}).items()
            },
            worst_run=str(worst.get("run") or ""),
            worst_fit=_num(worst.get("fit")),
            adequate=bool(m.get("adequate", True)),
            measured_modulators=tuple(str(x) for x in m.get("measured_modulators") or ()),
            sentence=str(m.get("sentence") or ""),
            heldout_runs=tuple(str(x) for x in m.get("heldout_runs") or ()),
            modulated_assessed=bool(m.get("modulated_assessed", True)),
            checks_passed=bool(m.get("checks_passed", True)),
        )

    def to_dict(self) -> dict[str, Any]:
        """The ``adequacy:`` mapping of ``params.yaml`` (NaN written as null)."""

        def f(x: float) -> float | None:
            return round(float(x), 3) if math.isfinite(x) else None

        return {
            "threshold": f(self.threshold),
            "noise_ceiling_fit": f(self.noise_ceiling_fit),
            "heldout_fit": {
                "median": f(self.heldout_median),
                "per_modulator": {k: f(v) for k, v in self.heldout_per_modulator.items()},
            },
            "insample_fit": {
                "median": f(self.insample_median),
                "per_modulator": {k: f(v) for k, v in self.insample_per_modulator.items()},
            },
            "worst_run": {"run": self.worst_run, "fit": f(self.worst_fit)},
            "adequate": bool(self.adequate),
            "measured_modulators": list(self.measured_modulators),
            "sentence": self.sentence,
            "heldout_runs": list(self.heldout_runs),
            "modulated_assessed": bool(self.modulated_assessed),
            "checks_passed": bool(self.checks_passed),
        }


def _pct(x: float) -> str:
    return f"{x:.0f} %" if math.isfinite(x) else "not available"


def adequacy_clause(adequacy: Adequacy | Mapping[str, Any] | None, modulator_type: str) -> str:
    """A plain clause for a sentence about ``modulator_type``; ``""`` when all is well.

    Parameters
    ----------
    adequacy : Adequacy, mapping or None
        The dataset's adequacy (``None``: not assessed, returns ``""``).
    modulator_type : str
        The modulator the sentence recommends (``"pwm"``, ...).

    Returns
    -------
    str
        ``""`` when the model is adequate and the modulator was run on this bench; else
        "the model does not describe this valve well enough (held-out FIT 62 % on run X)"
        and/or "not measured with this modulator on this bench", joined by "; ".

    Examples
    --------
    >>> a = Adequacy(adequate=False, worst_run="stair_pwm20", worst_fit=62.0,
    ...              measured_modulators=("pwm",))
    >>> adequacy_clause(a, "pwm")
    'the model does not describe this valve well enough (held-out FIT 62 % on run stair_pwm20)'
    >>> adequacy_clause(Adequacy(measured_modulators=("pwm",)), "dsm")
    'not measured with this modulator on this bench'
    """
    if adequacy is None:
        return ""
    a = adequacy if isinstance(adequacy, Adequacy) else Adequacy.from_mapping(adequacy)
    parts = []
    if not a.modulator_adequate(modulator_type):
        where = f" on run {a.worst_run}" if a.worst_run else ""
        parts.append(
            "the model does not describe this valve well enough "
            f"(held-out FIT {_pct(a.worst_fit)}{where})"
        )
    if modulator_type not in a.measured_modulators:
        parts.append("not measured with this modulator on this bench")
    return "; ".join(parts)


def assess(
    heldout: Mapping[str, float],
    insample: Mapping[str, float],
    ceiling: Mapping[str, float],
    modulators: Mapping[str, str],
    threshold: float = 80.0,
) -> Adequacy:
    """Adequacy from per-run FITs of the cycle-mean pressure.

    Parameters
    ----------
    heldout, insample, ceiling : mapping of run id to FIT %
        Leave-one-run-out FIT, in-sample FIT and noise ceiling of each run.
    modulators : mapping of run id to modulator type
        ``""`` for a run without a modulator (pulse, charge, discharge). When some runs have
        a modulator the verdict is taken over those runs (the use the model is made for);
        otherwise over all runs.
    threshold : float, optional
        Required held-out FIT in % of the noise ceiling.

    Returns
    -------
    Adequacy
    """
    if not (math.isfinite(threshold) and 0 < threshold <= 100):
        raise ValueError(
            f"identification.adequacy_threshold must be in (0, 100] %, got {threshold!r}"
        )
    modulated = [r for r in heldout if modulators.get(r)]
    use = modulated or list(heldout)
    use = [r for r in use if math.isfinite(heldout[r])]
    kinds = sorted({modulators[r] for r in modulated})
    per_held = {k: _median([heldout[r] for r in use if modulators.get(r) == k]) for k in kinds}
    per_in = {k: _median([insample[r] for r in use if modulators.get(r) == k]) for k in kinds}
    held = _median([heldout[r] for r in use])
    ins = _median([insample.get(r, math.nan) for r in use])
    ceil = _median([ceiling.get(r, math.nan) for r in use])
    worst = min(use, key=lambda r: heldout[r]) if use else ""
    a = Adequacy(
        threshold=float(threshold),
        noise_ceiling_fit=ceil,
        heldout_median=held,
        insample_median=ins,
        heldout_per_modulator=per_held,
        insample_per_modulator=per_in,
        worst_run=worst,
        worst_fit=heldout[worst] if worst else math.nan,
        measured_modulators=tuple(kinds),
    )
    required = a.required_fit
    ok = math.isfinite(held) and held >= required
    ok = ok and all(v >= required for v in per_held.values() if math.isfinite(v))
    # the runs by name when a reader can take them in; params.yaml lists them all
    named = len(use) <= 4
    held_out = ", ".join(use) if named else f"{len(use)} runs"
    if not use:
        sentence = "Model adequacy not assessed: no run with a valve command to predict."
        ok = True
    elif not modulated:
        # Repeats of the identification's own experiments predict each other: that they do
        # says the fits are consistent, not that the model describes modulated use.
        verdict = "are consistent" if ok else "are not consistent"
        sentence = (
            f"The identification's runs {verdict}: each of {held_out} predicted from the "
            f"others' parameters at held-out FIT {_pct(held)} (median; in-sample {_pct(ins)}, "
            f"{_pct(ceil)} the sensor noise allows). The modulated use is not assessed: no "
            "staircase, sine, chirp or closed-loop run was recorded."
        )
    elif ok:
        sentence = (
            f"The model describes this valve: held-out FIT {_pct(held)} (in-sample "
            f"{_pct(ins)}) against {_pct(ceil)} the sensor noise allows, on "
            f"{'the modulated runs ' if named else ''}{held_out}"
            f"{'' if named else ' with a modulator'}, each predicted from the parameters "
            "fitted without it."
        )
    else:
        sentence = (
            f"The model does not describe this valve well enough: held-out FIT {_pct(held)} "
            f"(in-sample {_pct(ins)}) against {_pct(ceil)} the sensor noise allows "
            f"(required {threshold:.0f} % of it) on {'the runs ' if named else ''}{held_out}, "
            "each predicted from "
            f"the parameters fitted without it; worst run {worst} at {_pct(a.worst_fit)}."
        )
    return replace(
        a,
        adequate=ok,
        sentence=sentence,
        heldout_runs=tuple(use),
        modulated_assessed=bool(modulated),
    )
