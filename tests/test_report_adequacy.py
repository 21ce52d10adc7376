"""What the page says adequacy held out (issue 46): the runs by name, and never repeats of
one experiment presented as evidence about modulated use."""

from __future__ import annotations

import pytest

from spa.report.params import adequacy_notes, identification_notes, modulated_assessed

# Five repeats of a charge and a discharge, no modulator: what a lab's unstamped logs give.
REPEATS = {
    "threshold": 80.0,
    "noise_ceiling_fit": 99.0,
    "heldout_fit": {"median": 96.0, "per_modulator": {}},
    "insample_fit": {"median": 97.0, "per_modulator": {}},
    "worst_run": {"run": "inflate-3", "fit": 90.0},
    "adequate": True,
    "measured_modulators": [],
    "sentence": "The model describes this valve: held-out FIT 96 % (in-sample 97 %).",
}
CONVENTION = {
    "chosen": "hold",
    "heldout_fit": {"hold": 96.0, "transport": 95.0},
    "heldout_fit_modulated": {"hold": 96.0, "transport": 95.0},
}


def _page_text(adequacy) -> str:
    return " ".join(identification_notes({"adequacy": adequacy, "delay_convention": CONVENTION}))


@pytest.mark.parametrize("new_keys", [True, False], ids=["heldout_runs", "older params.yaml"])
def test_repeats_without_a_modulator_are_not_evidence_about_modulated_use(new_keys):
    adequacy = dict(REPEATS)
    runs = ["inflate-1", "inflate-2", "deflate-1"]
    if new_keys:
        adequacy.update(heldout_runs=runs, modulated_assessed=False)
    text = _page_text(adequacy)
    assert "Modulated use not assessed" in text
    assert "the modulated runs" not in text and "on the modulated runs" not in text
    if new_keys:
        assert "Held out: runs inflate-1, inflate-2, deflate-1" in text


def test_modulated_runs_held_out_are_named_as_such():
    adequacy = {
        **REPEATS,
        "measured_modulators": ["pwm"],
        "heldout_runs": ["stair-pwm20", "stair-iipfm"],
        "modulated_assessed": True,
    }
    text = _page_text(adequacy)
    assert "Held out: the modulated runs stair-pwm20, stair-iipfm" in text
    assert "not assessed" not in text
    assert "held-out FIT on the modulated runs" in text  # the delay convention's


def test_the_flag_wins_over_the_measured_modulators():
    assert modulated_assessed({"measured_modulators": ["pwm"]}) is True
    flagged = {"measured_modulators": ["pwm"], "modulated_assessed": False}
    assert modulated_assessed(flagged) is False
    assert adequacy_notes({}) == [] and adequacy_notes(None) == []


def test_no_run_held_out_is_said_once():
    """Logs without a valve command: nothing is held out; the page does not speak of runs
    held out, and says once that the modulated use is not assessed."""
    sentence = (
        "Model adequacy not assessed: no run carries the valve command, so no run can be "
        "predicted from the others' parameters; the modulated use is not assessed."
    )
    none_held = {"heldout_runs": [], "modulated_assessed": False, "sentence": sentence}
    text = _page_text(none_held)
    assert "held out was made" not in text and text.count("not assessed") == 2
    assert adequacy_notes({**none_held, "sentence": ""}) == [
        "Modulated use not assessed: no run was held out."
    ]
