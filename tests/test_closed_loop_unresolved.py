"""A controller exported on an unresolved delay says so, in its header's comment and on the
page (issue 46: params.yaml marks a delay ``resolved: false``)."""

from __future__ import annotations

import pytest

from spa.closedloop.bench import apply_bench, bench_outputs
from spa.closedloop.comparison import closed_loop
from spa.closedloop.export import export_designed
from spa.identification.identified import read_identified
from spa.model.params import ValveParams

CFG = {
    "levels": [0.2, 0.5],
    "step_hold": 1.0,
    "sine": {"offset": 0.35, "amplitude": 0.1, "frequency": 0.5, "duration": 3.0, "skip": 1.0},
}
SELECTED = [{"type": "iipfm", "t_l": 0.02, "gain": 1.15}]
IDENTIFIED = {
    **ValveParams().as_dict(),
    "t_on": {"value": 0.05, "lo": 0.0, "hi": 0.05, "unit": "s", "resolved": False},
    "t_off": {"value": 0.009, "lo": 0.008, "hi": 0.010, "unit": "s"},
}


def unresolved_delays(identified):
    return read_identified(identified).unresolved
SAID = "t_on is not resolved by the data (interval [0, 50] ms)"


@pytest.fixture(scope="module")
def result():
    return closed_loop(ValveParams(), SELECTED, None, CFG)


def test_only_delays_marked_unresolved_are_read():
    assert unresolved_delays(IDENTIFIED) == {"t_on": (0.0, 0.05)}
    resolved = {**IDENTIFIED, "t_on": {**IDENTIFIED["t_on"], "resolved": True}}
    assert unresolved_delays(resolved) == {}
    assert unresolved_delays(ValveParams().as_dict()) == {}


def test_header_and_sentence_say_the_delay_is_unresolved(result):
    bench = bench_outputs(
        result, ValveParams(), None, CFG, 0.004, unresolved=unresolved_delays(IDENTIFIED)
    )
    comment = bench.header[: bench.header.index("*/")]
    assert SAID in comment and "record the valve command on the pressure's clock" in comment
    assert SAID in bench.sentence
    assert bench.summary["unresolved_delays"]["delays"] == {"t_on": [0.0, 0.05]}
    page = dict(result.controllers)
    res = type(result)(result.table, result.steps, result.traces, page, result.skipped)
    apply_bench(res, bench)
    assert SAID in res.controllers["sentence"]  # the sentence the page shows
    plain = bench_outputs(result, ValveParams(), None, CFG, 0.004)
    assert "not resolved" not in plain.header and "not resolved" not in plain.sentence


def test_design_for_dataset_reads_the_mark(monkeypatch):
    """The closed_loop stage (design_for_dataset) passes params.yaml's unresolved delays."""
    import spa.closedloop.bench as bench_module
    from spa.closedloop import promise

    seen = {}

    class Stop(Exception):
        pass

    def fake(*args, **kwargs):
        seen.update(kwargs)
        raise Stop

    monkeypatch.setattr(bench_module, "bench_outputs", fake)
    monkeypatch.setattr(
        "spa.closedloop.model_error.dataset_error", lambda *a, **k: {}, raising=True
    )
    identified = {"k2": {"value": 0.84, "lo": 0.83, "hi": 0.85}, **IDENTIFIED}
    with pytest.raises(Stop):
        promise.design_for_dataset(identified, {}, {}, SELECTED, CFG)
    assert seen["unresolved"] == {"t_on": (0.0, 0.05)}


def test_export_controller_says_it_was_not_checked_over_the_interval(tmp_path):
    header, _ = export_designed(
        tmp_path, ValveParams(), SELECTED[0], unresolved={"t_on": (0.0, 0.05)}
    )
    text = header.read_text()
    assert SAID in text and "designed at the estimate" in text
    plain, _ = export_designed(tmp_path / "plain", ValveParams(), SELECTED[0])
    assert "not resolved" not in plain.read_text()
