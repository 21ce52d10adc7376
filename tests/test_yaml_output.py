"""YAML written for people (spa.io.dump_yaml): no anchors or aliases, else safe_dump's bytes."""

from __future__ import annotations

import io

import yaml

from spa.io import dump_yaml


def test_a_shared_sub_dict_is_written_out_in_full():
    shared = {"type": "iipfm", "t_l": 0.02, "gain": 1.15}
    levels = [0.1, 0.4]
    data = {"setting": shared, "controllers": {"iipfm-20ms": {"setting": shared}}, "a": levels,
            "b": levels}  # fmt: skip
    assert "&id001" in yaml.safe_dump(data)  # what PyYAML does on its own
    text = dump_yaml(data, sort_keys=False)
    assert "&" not in text and "*" not in text
    assert text.count("type: iipfm") == 2
    assert yaml.safe_load(text) == data


def test_output_without_shared_parts_is_safe_dumps_byte_for_byte():
    data = {"z": 1.5, "a": [1, {"b": None, "c": "Δ ms"}], "n": float("nan"), "t": True}
    for options in ({}, {"sort_keys": False, "allow_unicode": True}, {"width": 100}):
        assert dump_yaml(data, **options) == yaml.safe_dump(data, **options)
    stream = io.StringIO()
    assert dump_yaml(data, stream, sort_keys=False) is None
    assert stream.getvalue() == yaml.safe_dump(data, sort_keys=False)


def test_every_yaml_writer_goes_through_the_helper():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    sources = [*(root / "spa").rglob("*.py"), *(root / "workflow").rglob("*.py")]
    offenders = [
        str(p.relative_to(root))
        for p in sources
        if p.name != "io.py"
        and any(f"yaml.{f}(" in p.read_text() for f in ("safe_dump", "dump", "dump_all"))
    ]
    assert offenders == []
