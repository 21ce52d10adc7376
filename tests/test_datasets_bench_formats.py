"""Bench file formats: MATLAB structs, dSpace recordings and v7.3 (HDF5), LabVIEW .lvm and
.tdms give the same run tables as the same data written as CSV; bad files get messages."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
import pytest
import scipy.io
import yaml
from file_writers import (
    dspace_recording,
    to_savemat,
    write_lvm,
    write_mat73,
    write_tdms,
)

import spa.datasets.contract as contract
import spa.datasets.readers.labview as labview
from spa.datasets import DatasetError, ingest_dataset, read_run_table, validate_dataset

MOD = {"type": "pwm", "f_w": 20}
SIG = "Platform/Model Root"


def _spec(folder: Path, runs: list[dict[str, Any]], **extra: Any) -> None:
    doc = {
        "name": folder.name,
        "description": "bench formats",
        "origin": "bench",
        "rig": {"valve": "v", "actuator": "a", "sensors": "s", "controller": "c"},
        **extra,
        "runs": runs,
    }
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))


def _data(n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3 + 0.25
    return {
        "t": t,
        "p_act": np.round(rng.uniform(0, 20, n), 4),  # psi
        "valve": (rng.random(n) < 0.5).astype(float),
        "u": np.round(rng.random(n), 6),
    }


def _folder(tmp_path: Path, name: str) -> Path:
    folder = tmp_path / "raw" / name
    folder.mkdir(parents=True)
    return folder


def _run(rid: str, file: str, kind: str = "staircase") -> dict[str, Any]:
    return {"id": rid, "kind": kind, "file": file, "modulator": MOD}


@pytest.fixture
def formats(tmp_path: Path) -> tuple[Path, dict[str, dict[str, np.ndarray]]]:
    """A dataset holding each format and, for each, the same data as CSV."""
    folder = _folder(tmp_path, "formats")
    data = {k: _data(300, i) for i, k in enumerate(["dspace", "v73", "lvm", "tdms"])}
    d = data["dspace"]
    rec = dspace_recording(
        "Time",
        d["t"],
        {f"{SIG}/Sensors/p_act": d["p_act"], f"{SIG}/Out/valve": d["valve"], f"{SIG}/In/u": d["u"]},
    )
    scipy.io.savemat(folder / "dspace.mat", {"rec": to_savemat(rec)})
    write_mat73(folder / "dspace73.mat", {"rec": rec})  # struct arrays of references
    v = data["v73"]
    write_mat73(
        folder / "v73.mat",
        {"t": v["t"], "p_act": v["p_act"], "valve": v["valve"].astype(bool), "u": v["u"]},
    )
    lv = data["lvm"]
    halves = [slice(0, 120), slice(120, 300)]
    write_lvm(
        folder / "rec.lvm",
        [
            [
                {
                    "X_Value": lv["t"][s],
                    "p_act": lv["p_act"][s],
                    "valve": lv["valve"][s],
                    "u": lv["u"][s],
                }
            ]
            for s in halves
        ],
    )
    td = data["tdms"]
    td["t"] = 0.25 + 1e-3 * np.arange(300, dtype=np.float64)
    write_tdms(
        folder / "rec.tdms",
        "Measured",
        [{k: td[k][s] for k in ("p_act", "valve", "u")} for s in halves],
        waveform=(0.25, 1e-3),
    )
    runs = []
    for key, file in [
        ("dspace", "dspace.mat"),
        ("v73", "v73.mat"),
        ("lvm", "rec.lvm"),
        ("tdms", "rec.tdms"),
    ]:
        runs += [_run(key, file), _run(f"{key}_csv", f"{key}.csv")]
        pd.DataFrame(data[key]).to_csv(folder / f"{key}.csv", index=False)
    runs.append(_run("dspace73", "dspace73.mat"))
    _spec(
        folder, runs, units={"pressure": "psi"}, columns={"p": "p_act", "valve": "valve", "u": "u"}
    )
    return folder, data


def test_every_format_ingests_to_the_values_of_its_csv(formats, tmp_path: Path) -> None:
    folder, data = formats
    assert validate_dataset(folder) == []
    paths = ingest_dataset(folder, tmp_path / "out")
    tables = {p.stem: read_run_table(p) for p in paths}
    for key in data:
        table, _ = tables[key]
        expected, _ = tables[f"{key}_csv"]
        pd.testing.assert_frame_equal(table, expected)
        np.testing.assert_array_equal(table["t"], data[key]["t"])  # s
        np.testing.assert_array_equal(table["p"], data[key]["p_act"] * 0.0689475729)  # bar
        assert len(table) == 300
    pd.testing.assert_frame_equal(tables["dspace73"][0], tables["dspace_csv"][0])
    assert tables["lvm"][1]["source"]["format"] == "lvm"
    assert tables["tdms"][1]["source"]["format"] == "tdms"
    assert tables["dspace"][1]["source"]["columns"] == {
        "t": "Time",
        "p": f"{SIG}/Sensors/p_act",
        "valve": f"{SIG}/Out/valve",
        "u": f"{SIG}/In/u",
    }
    assert tables["lvm"][1]["source"]["columns"]["t"] == "X_Value"


def test_lvm_blocks_and_segments_do_not_change_the_table(
    formats, tmp_path: Path, monkeypatch
) -> None:
    folder, _ = formats
    whole = read_run_table(ingest_dataset(folder, tmp_path / "a")[4])[0]
    monkeypatch.setattr(labview, "_BLOCK", 97)  # blocks cut mid-line and mid-marker
    monkeypatch.setattr(contract, "_BATCH_ROWS", 7)
    small = read_run_table(ingest_dataset(folder, tmp_path / "b")[4])[0]
    pd.testing.assert_frame_equal(whole, small)


def _problems(folder: Path, runs: list[dict[str, Any]], **extra: Any) -> str:
    _spec(folder, runs, **extra)
    text = "\n".join(str(p) for p in validate_dataset(folder))
    with pytest.raises(DatasetError):
        ingest_dataset(folder, folder.parent.parent / "out")
    return text


def test_struct_fields_and_rows_of_v73(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "fields")
    d = _data(50, 7)
    write_mat73(
        folder / "r.mat",
        {"rec": {"time": d["t"], "sensors": {"p": d["p_act"]}}, "u": d["u"]},
        row=True,
    )
    scipy.io.savemat(
        folder / "r5.mat", {"rec": {"time": d["t"], "sensors": {"p": d["p_act"]}}, "u": d["u"]}
    )
    runs = [_run("r", "r.mat", "sine"), _run("r5", "r5.mat", "sine")]
    _spec(folder, runs, columns={"t": "rec.time", "p": "rec.sensors.p"})
    assert [p.level for p in validate_dataset(folder)] == ["warning", "warning"]  # no valve
    a, b = (read_run_table(p)[0] for p in ingest_dataset(folder, tmp_path / "out"))
    pd.testing.assert_frame_equal(a, b)
    np.testing.assert_array_equal(a["p"], d["p_act"])


def test_bad_mat_files_name_what_the_file_holds(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "badmat")
    d = _data(20, 1)
    rec = dspace_recording(
        "Time", d["t"], {f"{SIG}/A/p_act": d["p_act"], f"{SIG}/B/p_act": d["p_act"]}
    )
    scipy.io.savemat(folder / "amb.mat", {"rec": to_savemat(rec)})
    write_mat73(
        folder / "types.mat",
        {"t": d["t"], "s": {"a": d["u"]}, "u": "text", "c": {"p_act": np.zeros((3, 4))}},
    )
    text = _problems(
        folder, [_run("amb", "amb.mat"), _run("typo", "types.mat")], columns={"p": "p_act"}
    )
    assert (
        "amb.mat [run 'amb', column 'p_act']: signal name 'p_act' is ambiguous: it ends "
        f"'{SIG}/A/p_act', '{SIG}/B/p_act'; give the full signal name"
    ) in text
    assert "missing signal 'u'" in text
    assert "missing signal 't'" not in text  # the one X entry is the time
    assert ("types.mat [run 'typo', column 'p_act']: missing MATLAB variable 'p_act'") in text
    assert "the struct fields 'c.p_act', 's.a'" in text and "(did you mean 'c.p_act'?)" in text
    (folder / "types.mat").unlink()
    write_mat73(
        folder / "types.mat",
        {"t": d["t"], "s": {"a": d["u"]}, "u": "text", "p_act": np.zeros((3, 4))},
    )
    text = _problems(folder, [_run("typo", "types.mat")], columns={"p": "p_act", "u": "s"})
    assert "MATLAB variable 'p_act' has shape 3×4" in text
    assert (
        "MATLAB variable 's' is a struct (fields 'a'); name one of its fields, e.g. 's.a'" in text
    )


def test_lvm_and_tdms_problems(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "badlv")
    d = _data(20, 2)
    write_lvm(folder / "a.lvm", [[{"X_Value": d["t"], "p": d["p_act"]}]], decimal=".")
    write_tdms(folder / "a.tdms", "G", [{"p": d["p_act"], "u": d["u"]}])  # no timing
    write_tdms(folder / "b.tdms", "H", [{"p": d["p_act"], "u": d["u"]}], waveform=(0, 1e-3))
    (folder / "c.tdms").write_bytes(b"TDSm" + b"\x00" * 40)
    (folder / "c.lvm").write_text("time;p\n0;1\n")
    text = _problems(
        folder, [_run("a", "a.lvm"), _run("b", "a.tdms"), _run("c", "c.tdms"), _run("d", "c.lvm")]
    )
    assert (
        "a.lvm [run 'a', column 'u']: missing LabVIEW channel 'u': a staircase run needs "
        "input fraction u (u); the file has the channels 'X_Value', 'p'"
    ) in text
    assert ("a.tdms [run 'b', column 't']: missing LabVIEW channel 't'") in text
    assert "the file has the channels 'G/p', 'G/u' and no waveform timing" in text
    assert "c.tdms [run 'c']: unreadable TDMS file" in text
    assert "c.lvm [run 'd']: not a LabVIEW measurement file" in text


def test_tdms_channels_by_group_and_mixed_timing(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "tdms")
    d = _data(30, 3)
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(folder / "m.tdms")) as w:
        w.write_segment(
            [
                ChannelObject("A", "p", d["p_act"], {"wf_increment": 1e-3}),
                ChannelObject("B", "p", d["p_act"], {"wf_increment": 1e-3}),
                ChannelObject("B", "u", d["u"], {"wf_increment": 2e-3}),
            ]
        )
    text = _problems(folder, [_run("m", "m.tdms")])
    assert "channel name 'p' is in several groups ('A/p', 'B/p')" in text
    text = _problems(folder, [_run("m", "m.tdms")], columns={"p": "B/p"})
    assert "do not share one waveform timing" in text
    assert "p: (0.0, 0.001), u: (0.0, 0.002)" in text


def test_v73_is_detected_by_its_header_and_read_in_slices(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "v73")
    d = _data(40, 4)
    write_mat73(folder / "r.mat", {k: d[k] for k in ("t", "p_act", "u")})
    assert (folder / "r.mat").read_bytes()[:10] == b"MATLAB 7.3"
    with h5py.File(folder / "r.mat") as f:
        assert f["p_act"].shape == (1, 40)  # MATLAB's n×1, transposed
    _spec(folder, [_run("r", "r.mat")], columns={"p": "p_act"})
    assert [p.level for p in validate_dataset(folder)] == ["warning"]


def test_good_bench_corpus_passes_with_the_same_values_in_every_format(tmp_path: Path) -> None:
    folder = Path(__file__).parent / "corpus" / "good" / "spa_good_bench"
    assert validate_dataset(folder) == []
    tables = [read_run_table(p)[0] for p in ingest_dataset(folder, tmp_path / "out")]
    assert len(tables) == 4
    for table in tables[1:]:
        pd.testing.assert_frame_equal(table, tables[0])
    assert tables[0]["p"].max() == pytest.approx(
        8 * (1 - np.exp(-0.299 / 0.08)) * 0.0689475729, abs=1e-6
    )


def test_v73_links_to_other_files_are_refused(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "links")
    outside = tmp_path / "outside.h5"
    with h5py.File(outside, "w") as f:
        f["p"] = np.ones(5)
    d = _data(5, 5)
    write_mat73(folder / "r.mat", {"t": d["t"]})
    with h5py.File(folder / "r.mat", "a") as f:
        f["p"] = h5py.ExternalLink(str(outside), "p")
    write_mat73(folder / "e.mat", {"t": d["t"]})
    with h5py.File(folder / "e.mat", "a") as f:
        f.create_dataset("p", shape=(1, 5), dtype="f8", external=[(str(outside), 0, 40)])
    text = _problems(folder, [_run("r", "r.mat", "charge"), _run("e", "e.mat", "charge")])
    assert "r.mat [run 'r']: /p is a link, not data" in text
    assert "e.mat [run 'e']: /p keeps its data in other files" in text


def test_dspace_time_is_named_when_there_are_several_x_entries(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "twox")
    d = _data(20, 6)
    rec = dspace_recording("Time", d["t"], {f"{SIG}/p": d["p_act"]})
    rec["X"].append({"Name": "Time2", "Data": d["t"].reshape(1, -1)})
    scipy.io.savemat(folder / "r.mat", {"rec": to_savemat(rec)})
    text = _problems(folder, [_run("r", "r.mat", "charge")])
    assert "missing signal 't': a charge run needs time (t)" in text
    assert "the dSpace signals 'Time', 'Time2', 'Platform/Model Root/p'" in text
    # p_act is in psi (up to 20): declared bar, a 19 bar supply is warned about as likely psi
    _spec(folder, [_run("r", "r.mat", "charge")], columns={"t": "Time2", "p": "p"})
    (warning,) = validate_dataset(folder)
    assert warning.level == "warning" and warning.message.endswith("{pressure: psi} if so)")
    units = {"pressure": "psi"}
    _spec(folder, [_run("r", "r.mat", "charge")], columns={"t": "Time2", "p": "p"}, units=units)
    assert validate_dataset(folder) == []


def test_lvm_text_value_and_tdms_text_channel_are_named(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "texts")
    d = _data(20, 8)
    write_lvm(folder / "a.lvm", [[{"X_Value": d["t"], "p": d["p_act"]}]])
    data = (folder / "a.lvm").read_bytes()
    (folder / "a.lvm").write_bytes(
        data.replace(b"\t" + str(d["p_act"][4]).replace(".", ",").encode(), b"\tabc", 1)
    )
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(folder / "b.tdms")) as w:
        w.write_segment([ChannelObject("G", "t", d["t"]), ChannelObject("G", "p", ["x"] * 20)])
    text = _problems(folder, [_run("a", "a.lvm", "charge"), _run("b", "b.tdms", "charge")])
    assert "a.lvm [run 'a', column 'p', row 5]: non-numeric value" in text
    assert "b.tdms [run 'b', column 'p']: LabVIEW channel 'G/p' holds" in text
    assert "not numbers; expected a numeric channel" in text


@pytest.mark.parametrize(
    ("kind", "needle"),
    [
        ("v5", "MATLAB variable 'p' declares 1x2000000 double = 2,000,000 values; at most 100,000"),
        ("v5_struct", "MATLAB variable 's': its "),
        ("v73", "declares 1099511627776x1 = 1,099,511,627,776 values (8,796,093,022,208 bytes)"),
    ],
)
def test_a_mat_file_declaring_more_than_it_may_is_refused_without_reading_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kind: str, needle: str
) -> None:
    """16 MB of compressed zeros (a vector, or a struct's field that the header does not
    size) against a limit of 1e5 samples, and a v7.3 file declaring 2^40 samples: one error
    naming the variable and the sizes, and validating allocates under 4 MB."""
    import tracemalloc

    from file_writers import write_v5_zeros, write_v73_declared

    from spa.datasets import validate_dataset

    monkeypatch.setenv("SPA_MAX_SAMPLES", "1e5")
    folder = tmp_path / "ds"
    folder.mkdir()
    if kind == "v73":
        write_v73_declared(folder / "run.mat", 2**40)
    else:
        write_v5_zeros(folder / "run.mat", 2_000_000, in_struct=kind == "v5_struct")
    (folder / "dataset.yaml").write_text(
        "name: ds\ndescription: x\norigin: bench\nrig: {}\n"
        "runs:\n- {id: c, kind: charge, file: run.mat}\n"
    )
    assert (folder / "run.mat").stat().st_size < 50_000
    validate_dataset(tmp_path / "none")  # the readers' imports, before counting
    import h5py  # noqa: F401
    import scipy.io  # noqa: F401

    tracemalloc.start()
    problems = validate_dataset(folder)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert [p.level for p in problems] == ["error"]
    assert needle in problems[0].message and problems[0].run == "c"
    assert peak < 4e6, peak
