"""A MATLAB v5 file is read for the variables dataset.yaml names, never for the others."""

from __future__ import annotations

import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import scipy.io
from file_writers import append_v5_zeros

from spa.datasets import validate_dataset

ROOT = Path(__file__).resolve().parents[1]
MAT = "staircase_iipfm-20ms-G1.2.mat"


def _dataset_with_junk(tmp_path: Path, n: int) -> Path:
    """raw/example, its MAT run saved compressed with three unnamed variables of n zeros."""
    folder = tmp_path / "example"
    shutil.copytree(ROOT / "raw" / "example", folder)
    data = {k: v for k, v in scipy.io.loadmat(folder / MAT).items() if not k.startswith("__")}
    scipy.io.savemat(folder / MAT, data, do_compression=True)
    append_v5_zeros(folder / MAT, ["junk_a", "junk_b", "junk_c"], n)
    return folder


def test_unnamed_variables_are_never_loaded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    folder = _dataset_with_junk(tmp_path, 1000)
    calls: list[object] = []
    loadmat = scipy.io.loadmat

    def spy(*args, **kwargs):
        calls.append(kwargs.get("variable_names"))
        return loadmat(*args, **kwargs)

    monkeypatch.setattr(scipy.io, "loadmat", spy)
    problems = validate_dataset(folder)
    assert not [p for p in problems if p.level == "error"], problems
    assert calls and None not in calls  # never "every variable"
    asked = {name for names in calls for name in names}
    assert asked == {"time_ms", "P_act_kPa", "valve_cmd", "xi_ref"}


def test_three_unnamed_512_mib_variables_cost_no_memory(tmp_path: Path) -> None:
    """The issue's MAT bomb: about 2 MB on disk, 1.5 GiB if expanded; `spa validate` stays
    under 300 MB (its own peak resident memory: VmHWM of /proc/self/status at exit, which is
    the process's own; the rusage of a child also counts the parent it was forked from)."""
    folder = _dataset_with_junk(tmp_path, (512 << 20) // 8)
    assert (folder / MAT).stat().st_size < 4e6
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    peak = (
        "import atexit, runpy, sys\n"
        "def peak():\n"
        "    status = open('/proc/self/status').read()\n"
        "    print('VmHWM_kB', status.split('VmHWM:')[1].split()[0], flush=True)\n"
        "atexit.register(peak)\n"
        f"sys.argv = ['spa', 'validate', {str(folder)!r}]\n"
        "runpy.run_module('spa', run_name='__main__')\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", peak], cwd=ROOT, capture_output=True, text=True, check=False
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    hwm = int(proc.stdout.split("VmHWM_kB")[1].split()[0])
    assert hwm * 1024 < 300e6, hwm
    # CPU time, not wall time: a loaded machine stretches the second, not the first (5 s of
    # wall on an idle machine: benchmarks/README.md); expanding the bomb would cost minutes
    assert cpu < 60, cpu
