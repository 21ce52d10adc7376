"""Probe campaign: spa used as a careless or hostile user would, each probe checked.

Run from the repository root (everything happens in temporary folders):

    .venv/bin/python benchmarks/probe_campaign.py            # every probe
    .venv/bin/python benchmarks/probe_campaign.py -k yaml    # the probes whose name has 'yaml'

A probe passes when spa answers with a clear message (naming the file, run, key or argument)
and no traceback from deep inside a library, in bounded time, and nothing under the
repository's raw/ changed. Snakemake probes use a copy of raw/example, never raw/ itself.
The last line says how many probes ran and how many failed; the exit status is 1 if any did.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
Probe = Callable[[Path], tuple[bool, str]]
PROBES: dict[str, Probe] = {}


def probe(fn: Probe) -> Probe:
    PROBES[fn.__name__.removeprefix("probe_")] = fn
    return fn


def tree_digest(folder: Path) -> str:
    h = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        h.update(str(path.relative_to(folder)).encode() + path.read_bytes())
    return h.hexdigest()


def sh(args: list[str], cwd: Path = ROOT, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout)


def clean(res: subprocess.CompletedProcess, *needles: str) -> tuple[bool, str]:
    """A refusal from a command: non-zero exit, every needle in the output, no traceback."""
    text = res.stdout + res.stderr
    missing = [n for n in needles if n not in text]
    traceback = "Traceback (most recent call last)" in text
    ok = res.returncode != 0 and not missing and not traceback
    if ok:
        return True, "refused clearly"
    return False, f"exit {res.returncode}; missing {missing}; traceback: {traceback}"


def snakemake(tmp: Path, *config: str, target: str = "-n") -> subprocess.CompletedProcess:
    raw = tmp / "raw"
    if not raw.exists():
        shutil.copytree(ROOT / "raw" / "example", raw / "example")
    return sh(
        [
            PY,
            "-m",
            "snakemake",
            target,
            "--configfile",
            "config/small.yaml",
            "--config",
            f"datasets={{raw_dir: {raw}}}",
            *config,
        ]
    )


def api(code: str, *needles: str) -> Probe:
    def run(tmp: Path) -> tuple[bool, str]:
        # A refusal from the API: a ValueError or TypeError (spa's own subclasses included)
        # whose message has the needles, not an IndexError or AttributeError from inside.
        res = sh([PY, "-c", f"import numpy as np, spa\n{code}"], cwd=tmp)
        last = (res.stderr.strip().splitlines() or [""])[-1]
        kind = last.split(":", 1)[0].rsplit(".", 1)[-1]
        missing = [n for n in needles if n not in last]
        ok = res.returncode != 0 and kind.endswith(("ValueError", "TypeError")) and not missing
        return ok, "refused clearly" if ok else f"{last[:200]!r}; missing {missing}"

    return run


# ---- data loss --------------------------------------------------------------------------
for value, needle in [
    ("raw", "is the raw-data folder"),
    ("/", "file-system root"),
    (".", "contains the raw-data folder"),
    ("raw/example", "inside the raw-data folder"),
]:

    def _p(tmp: Path, value: str = value, needle: str = needle) -> tuple[bool, str]:
        raw = tmp / "raw"
        shutil.copytree(ROOT / "raw" / "example", raw / "example")
        target = {"raw": str(raw), ".": str(tmp), "raw/example": str(raw / "example")}
        res = sh(
            [
                PY,
                "-m",
                "snakemake",
                "-n",
                "--configfile",
                "config/small.yaml",
                "--config",
                f"results={target.get(value, value)}",
                f"datasets={{raw_dir: {raw}}}",
            ]
        )
        return clean(res, needle)

    PROBES[f"results_{value.replace('/', '_') or 'empty'}"] = _p


@probe
def probe_ingest_into_another_dataset(tmp: Path) -> tuple[bool, str]:
    raw = tmp / "raw"
    for name in ("a", "b"):
        shutil.copytree(ROOT / "raw" / "example", raw / name)
    before = tree_digest(raw / "b")
    res = sh([PY, "-m", "spa", "ingest", str(raw / "a"), str(raw / "b")])
    ok, why = clean(res, "inside")
    return ok and tree_digest(raw / "b") == before, why


@probe
def probe_ingest_into_a_full_folder(tmp: Path) -> tuple[bool, str]:
    (tmp / "mine").mkdir()
    (tmp / "mine" / "thesis.tex").write_text("irreplaceable")
    res = sh([PY, "-m", "spa", "ingest", str(ROOT / "raw" / "example"), str(tmp / "mine")])
    return clean(res, "is not empty and is not the output of an earlier ingest")


@probe
def probe_dataset_named_logs(tmp: Path) -> tuple[bool, str]:
    shutil.copytree(ROOT / "raw" / "example", tmp / "raw" / "logs")
    return clean(snakemake(tmp), "dataset name 'logs' is reserved")


# ---- hostile dataset.yaml ----------------------------------------------------------------
def _yaml_probe(text: str, needle: str) -> Probe:
    def run(tmp: Path) -> tuple[bool, str]:
        folder = tmp / "d"
        folder.mkdir()
        (folder / "dataset.yaml").write_text(text)
        start = time.perf_counter()
        res = sh([PY, "-m", "spa", "validate", str(folder)], timeout=30)
        ok, why = clean(res, needle)
        return ok and time.perf_counter() - start < 10, why

    return run


_bomb = "name: d\na0: &a0 [l, l, l, l, l, l, l, l, l]\n" + "".join(
    f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]\n" for i in range(1, 10)
)
PROBES["yaml_alias_bomb"] = _yaml_probe(_bomb + "runs: *a9\n", "aliases are expanded")
PROBES["yaml_deep"] = _yaml_probe("runs: " + "[" * 5000 + "]" * 5000, "nested more than")
PROBES["yaml_huge"] = _yaml_probe("name: d\ndescription: " + "x" * (2 << 20), "at most")
PROBES["modulator_true"] = _yaml_probe(
    "name: d\ndescription: x\norigin: bench\nrig: {}\nruns:\n- {id: s, kind: staircase, "
    "file: s.csv, modulator: {type: pwm, f_w: true}}\n",
    "must be a number",
)


# ---- hostile CSV (read by the contract's readers) ----------------------------------------
def _csv_probe(content: bytes, needle: str, name: str = "run.csv") -> Probe:
    def run(tmp: Path) -> tuple[bool, str]:
        folder = tmp / "d"
        folder.mkdir()
        (folder / "dataset.yaml").write_text(
            "name: d\ndescription: x\norigin: bench\nrig: {}\n"
            f"runs:\n- {{id: c, kind: charge, file: {json.dumps(name)}}}\n"
        )
        (folder / name).write_bytes(content)
        res = sh([PY, "-m", "spa", "validate", str(folder)], timeout=60)
        return clean(res, needle)

    return run


_rows = "".join(f"{k * 0.001:.3f},{min(k, 500) * 0.001:.4f},1\n" for k in range(1000))
PROBES["csv_cr_only"] = _csv_probe(("t,p,valve\n" + _rows).replace("\n", "\r").encode(), "\\r")
PROBES["csv_long_line"] = _csv_probe(b"t,p,valve\n" + b"1" * (50 << 20) + b"\n", "line 2")
PROBES["csv_400_digits"] = _csv_probe(("t,p,valve\n0," + "9" * 400 + ",1\n").encode(), "row")
PROBES["csv_utf16_no_bom"] = _csv_probe(("t,p,valve\n" + _rows).encode("utf-16-le"), "UTF-16")
_ULP = repr(float(np.nextafter(1.0, 2.0)))
PROBES["csv_u_one_ulp_over"] = _csv_probe(
    ("t,p,valve,u\n" + "".join(f"{k}e-3,0.1,1,{_ULP}\n" for k in range(9))).encode(),
    "1.0000000000000002",
)
PROBES["csv_name_needs_escaping"] = _csv_probe(
    b"t,p,valve\n0,x,1\n0.001,0.1,1\n", "non-numeric", name="run 'ä' #1.csv"
)

# ---- hostile arguments to the Python API -------------------------------------------------
PROBES["api_modulate_tiny_fw"] = api(
    "spa.modulate('pwm', np.full(100, .5), 1e-3, f_w=1e-300)", "'f_w' = 1e-300 is outside"
)
PROBES["api_modulate_above_nyquist"] = api(
    "spa.modulate('pwm', np.full(100, .5), 1e-3, f_w=900)", "above half the controller rate"
)
PROBES["api_simulate_params_dict"] = api(
    "spa.simulate(np.ones(9, np.int8), 1e-3, {'c1': .5})", "params must be a ValveParams"
)
PROBES["api_bicoherence_one_segment"] = api(
    "spa.bicoherence(np.random.default_rng(0).normal(size=256), 1e3, nfft=256)", "1 segment"
)


# ---- numbers that mislead ----------------------------------------------------------------
def numbers(code: str) -> Probe:
    """A claim checked in a fresh interpreter: it passes when the code prints 'ok ...'."""

    def run(tmp: Path) -> tuple[bool, str]:
        res = sh([PY, "-c", f"import numpy as np, pandas as pd, spa\n{code}"], cwd=tmp)
        last = (res.stdout.strip().splitlines() or [res.stderr.strip()[-200:]])[-1]
        return res.returncode == 0 and last.startswith("ok"), last

    return run


PROBES["table2_exact_optimum_meets_the_constraints"] = numbers(
    "from spa.tuning import tune\n"
    "from spa.tuning.recommend import setting_metrics\n"
    "from spa.tuning.exact import COST_TIE\n"
    "from spa.model.modulators import get_kind\n"
    "v = spa.ValveParams(c1=0.45, k2=1.05, tau2=0.70, t_on=0.004, t_off=0.009)\n"
    "t = tune(v).table2.set_index('modulator')\n"
    "s = {k: r.optimum_exact * get_kind(k).unscale for k, r in t.iterrows()}\n"
    "c = {k: float(setting_metrics(k, x, v)['chattering']) for k, x in s.items()}\n"
    "# J's optimum is ranked by J except where J ties (LPWM: rounding error), flagged then\n"
    "ranked = t[t.J_min > COST_TIE]\n"
    "edge = ranked.optimum_at_grid_edge.any() or t.optimum_exact_at_grid_edge.any()\n"
    "bad = max(c.values()) > 0.05 or edge\n"
    "print(('FAIL ' if bad else 'ok ') + str(dict(t.optimum_exact)) + ' chattering ' + str(c))"
)
PROBES["chirp_reference_through_the_runs_sensor"] = numbers(
    "from spa.openloop import chirp_reference, no_ringing_spread\n"
    "from spa.synthetic import generate_dataset\n"
    "from spa.datasets import read_runs\n"
    "cfg = {'params': spa.ValveParams().as_dict(), 'controller_dt': 1e-3,\n"
    "       'sensor': {'fs': 1e3, 'noise': 0.005, 'quantum': 0.001,\n"
    "                  'ringing': {'amplitude': 0.01, 'frequency': 60.0, 'damping': 60.0}},\n"
    "       'modulators': [{'type': 'pwm', 'f_w': 20.0}]}\n"
    "exp = {'chirp': {'f0': 0.1, 'f1': 100.0, 'duration': 30.0, 'offset': 0.5,\n"
    "                 'amplitude': 0.25}}\n"
    "generate_dataset('p', cfg, exp, 1, 'runs')\n"
    "runs, metas = read_runs('runs')\n"
    "run, meta = runs['chirp_pwm-20Hz'], metas['chirp_pwm-20Hz']\n"
    "o = {'nfft': 128, 'decimate': 4}\n"
    "ref = chirp_reference(run, spa.ValveParams(), [meta['modulator']], meta, 2, **o)[2]\n"
    "quiet = no_ringing_spread(meta, 2, **o)\n"
    "a, b = ref['significant_fraction'], ref['significant_fraction_no_ringing']\n"
    "print(('ok ' if b < a and quiet else 'FAIL ') + f'linear {a:.4f}, without ringing {b:.4f}')"
)
PROBES["sine_lag_beyond_2_s_found_or_flagged"] = numbers(
    "from spa.openloop import sine_analysis\n"
    "t = np.arange(0, 300, 0.01)\n"
    "u = 0.5 + 0.4 * np.sin(2 * np.pi * 0.02 * t)\n"
    "run = pd.DataFrame({'t': t, 'u': u, 'p': np.roll(u, 350)})\n"
    "found, lim = sine_analysis(run)[1], sine_analysis(run, max_lag=2.0)[1]\n"
    "good = abs(found['lag'] - 3.5) < 0.1 and np.isnan(lim['lag']) and lim['lag_at_limit']\n"
    "print(('ok ' if good else 'FAIL ') + f\"lag {found['lag']}, limited {lim['lag']}\")"
)


# ---- configuration -----------------------------------------------------------------------
for name, value, needle in [
    ("sweep_backwards", "analytic={sweeps: {pwm: {start: 80, stop: 1, step: 1}}}", "below stop"),
    ("controller_dt", "simulated={sim: {controller_dt: 0.003}}", "whole number of controller"),
    ("seed_text", "seed=abc", "seed: 'abc' is not of type 'integer'"),
]:

    def _c(tmp: Path, value: str = value, needle: str = needle) -> tuple[bool, str]:
        return clean(snakemake(tmp, value), needle)

    PROBES[f"config_{name}"] = _c


# ---- trust: missing outputs, the environment, stray files (issue 25) ----------------------
# Full runs of the small configuration share one copy of raw/example and one clean run, to
# compare with byte for byte (logs, the report page and the recommendation's source line,
# which names the results folder, aside).
_SHARED: dict[str, Path] = {}


def _shared() -> Path:
    if "tmp" not in _SHARED:
        _SHARED["tmp"] = Path(tempfile.mkdtemp(prefix="spa-probe-shared-"))
        shutil.copytree(ROOT / "raw" / "example", _SHARED["tmp"] / "raw" / "example")
    return _SHARED["tmp"]


def _full(results: Path) -> subprocess.CompletedProcess:
    raw = _shared() / "raw"
    cmd = [PY, "-m", "snakemake", "reproduce-all", "-c1", "--configfile", "config/small.yaml",
           "--config", f"results={results}", f"datasets={{raw_dir: {raw}}}"]  # fmt: skip
    return sh(cmd, timeout=1800)


def _files(folder: Path) -> dict[str, bytes]:
    found = {}
    for path in sorted(folder.rglob("*")):
        rel = str(path.relative_to(folder))
        if path.is_file() and not rel.startswith("logs/") and rel != "report.html":
            data = path.read_bytes()
            found[rel] = data.split(b"\n", 1)[1] if path.name == "recommendation.yaml" else data
    return found


def _clean() -> dict[str, bytes]:
    if "clean" not in _SHARED:
        res = _full(_shared() / "clean")
        if res.returncode != 0:
            raise RuntimeError(f"the clean run failed: {res.stderr[-2000:]}")
        _SHARED["clean"] = _shared() / "clean"
    return _files(_SHARED["clean"])


def _same_as_clean(results: Path) -> str:
    clean, got = _clean(), _files(results)
    differ = sorted(k for k in clean.keys() | got.keys() if clean.get(k) != got.get(k))
    return "equal to a clean run" if not differ else f"{len(differ)} files differ: {differ[:3]}"


@probe
def probe_rebuild_deleted_folder_run_table_and_altered_table(tmp: Path) -> tuple[bool, str]:
    out = tmp / "results"
    first = _full(out)
    if first.returncode != 0:
        return False, f"first run failed: {first.stderr[-500:]}"
    shutil.rmtree(out / "example" / "staircase")
    (out / "sim" / "runs" / "sine_dsm-20ms.parquet").unlink()
    with (out / "analytic" / "table1.csv").open("a") as fh:
        fh.write("0,0,0\n")
    again = _full(out)
    why = _same_as_clean(out)
    ok = again.returncode == 0 and why.startswith("equal")
    return ok, f"rerun exit {again.returncode}; {why}"


def _environment_probe(fault: str, free: str) -> Probe:
    """A run under ``fault`` (shell lines, in a mount namespace of their own), then, once
    ``free`` lifted it, a rerun in the same results folder: the first must fail saying it is
    the environment, with no status file blaming the data; the rerun must equal a clean run."""

    def run(tmp: Path) -> tuple[bool, str]:
        out, copy = tmp / "results", tmp / "copy"
        out.mkdir()
        copy.mkdir()
        raw = _shared() / "raw"
        cmd = " ".join(f"'{c}'" for c in [
            PY, "-m", "snakemake", "reproduce-all", "-c1", "--configfile", "config/small.yaml",
            "--config", f"results={out}", f"datasets={{raw_dir: {raw}}}"])  # fmt: skip
        script = (
            f"cd '{ROOT}'; {fault.format(out=out)}\n({cmd}) 2>&1; echo FAULT_EXIT=$?\n"
            f"echo BLAMED=$(grep -rlE 'No space left|File too large' '{out}' --include='*.json'"
            f" | wc -l)\n{free.format(out=out)}\n{cmd} > '{tmp}/rerun.log' 2>&1; rc=$?\n"
            f"cp -a '{out}/.' '{copy}/'; echo RERUN_EXIT=$rc"
        )
        res = sh(["unshare", "-m", "bash", "-c", script], timeout=3600)
        text = res.stdout + res.stderr
        fields = dict(line.split("=", 1) for line in text.splitlines() if line[:6] in (
            "FAULT_", "BLAMED", "RERUN_"))  # fmt: skip
        said = "stopped by its environment, not by its data" in text
        why = _same_as_clean(copy)
        ok = (fields.get("FAULT_EXIT") not in (None, "0") and said
              and fields.get("BLAMED") == "0" and fields.get("RERUN_EXIT") == "0"
              and why.startswith("equal"))  # fmt: skip
        return ok, (
            f"faulty run exit {fields.get('FAULT_EXIT')}, says environment: {said}, status "
            f"files blaming the data: {fields.get('BLAMED')}; rerun exit "
            f"{fields.get('RERUN_EXIT')}, {why}"
        )

    return run


# The results folder on a 3 MB file system (a small run writes about 30 MB): ENOSPC; then
# the file system grows to 1 GB.
PROBES["env_full_disk_then_rerun"] = _environment_probe(
    "mount -t tmpfs -o size=3m tmpfs '{out}' || exit 9", "mount -o remount,size=1g '{out}'"
)
# Files above 150 kB refused by the shell's limit (ulimit -f): EFBIG; the rerun has none.
PROBES["env_file_size_limit_then_rerun"] = _environment_probe(
    "ulimit -S -f 150", "ulimit -S -f unlimited"
)


@probe
def probe_env_injected_enospc(tmp: Path) -> tuple[bool, str]:
    code = (
        "import errno, logging, sys\nfrom pathlib import Path\nfrom types import SimpleNamespace\n"
        "from spa.pipeline.jobs import Names\nfrom spa.pipeline.status import run_stage\n"
        "from spa.pipeline.outputs import stage_outputs\n"
        f"base = Path({str(tmp)!r})\n"
        "out = {k: str(base / v) for k, v in stage_outputs('sine', 'r', 'd').items()}\n"
        "job = SimpleNamespace(output=Names(out), wildcards=Names({'dataset': 'd'}))\n"
        "def work():\n    raise OSError(errno.ENOSPC, 'No space left on device', out['table'])\n"
        "run_stage(job, 'sine', work, logging.getLogger('x'))\n"
    )
    res = sh([PY, "-c", code], cwd=tmp)
    left = [p for p in tmp.rglob("*") if p.is_file()]
    ok = res.returncode == 1 and "not by its data" in res.stderr and not left
    return ok, f"exit {res.returncode}, files left {len(left)}: {res.stderr.strip()[-160:]}"


def _stray(raw: Path) -> None:
    folder = raw / "example"
    (folder / "dangling").symlink_to(raw / "nowhere")
    os.mkfifo(folder / "pipe")
    (folder / os.fsdecode(b"Pr\xfcfung.csv")).write_text("x")  # a Windows zip's Latin-1 name
    for junk in [".DS_Store", "Thumbs.db", "~$notes.xlsx"]:
        (folder / junk).write_text("x")
    (raw / "stray").mkdir()  # no dataset.yaml: not a dataset
    (raw / "stray" / "a.csv").write_text("x")
    shutil.copytree(
        folder,
        raw / os.fsdecode(b"Pr\xfcfstand"),
        symlinks=True,
        ignore=shutil.ignore_patterns("pipe"),
    )  # a dataset named in Latin-1


@probe
def probe_raw_stray_files(tmp: Path) -> tuple[bool, str]:
    shutil.copytree(ROOT / "raw" / "example", tmp / "raw" / "example")
    _stray(tmp / "raw")
    dry = snakemake(tmp)
    val = sh([PY, "-m", "spa", "validate", str(tmp / "raw" / "example")], timeout=60)
    listed = "3 file(s) of the folder that no run names are ignored" in val.stdout
    ok = dry.returncode == 0 and val.returncode == 0 and listed
    return ok, f"dry run exit {dry.returncode}; validate exit {val.returncode}, listed: {listed}"


@probe
def probe_raw_named_run_file_is_a_pipe(tmp: Path) -> tuple[bool, str]:
    raw = tmp / "raw"
    shutil.copytree(ROOT / "raw" / "example", raw / "example")
    (raw / "example" / "pulse.csv").unlink()
    os.mkfifo(raw / "example" / "pulse.csv")
    dry = snakemake(tmp)
    val = sh([PY, "-m", "spa", "validate", str(raw / "example")], timeout=60)
    ok, why = clean(val, "'pulse.csv' is not a regular file")
    return ok and dry.returncode == 0, f"dry run exit {dry.returncode}; validate: {why}"


@probe
def probe_input_not_a_staircase(tmp: Path) -> tuple[bool, str]:
    import pyarrow.parquet as pq

    raw = tmp / "raw"
    shutil.copytree(ROOT / "raw" / "example", raw / "example")
    path = raw / "example" / "staircase_pwm-20Hz.parquet"
    table = pq.read_table(path).to_pandas()
    table[table.columns[-1]] = 0.5 + 0.4 * np.sin(np.arange(len(table)) / 500.0)
    import pyarrow as pa

    pq.write_table(pa.Table.from_pandas(table, preserve_index=False), path)
    out = tmp / "results"
    res = sh([PY, "-m", "snakemake", f"{out}/example/staircase/table3.csv", "-c1", "--configfile",
              "config/small.yaml", "--config", f"results={out}", f"datasets={{raw_dir: {raw}}}"],
             timeout=900)  # fmt: skip
    log = (out / "logs" / "example" / "staircase.log").read_text()
    text = res.stdout + res.stderr
    ok = "labelled staircase but u goes down" in log + text and "Traceback" not in log + text
    return ok, f"exit {res.returncode}; traceback on console or in log: {'Traceback' in log + text}"


def _unshare_ro(folder: Path, args: list[str]) -> subprocess.CompletedProcess:
    line = " ".join(f"'{a}'" for a in args)
    return sh(["unshare", "-m", "sh", "-c", f"mount --bind -o ro '{folder}' '{folder}' && {line}"])


@probe
def probe_init_read_only_folder(tmp: Path) -> tuple[bool, str]:
    rec = tmp / "rec"
    rec.mkdir()
    for name in ["charge.csv", "discharge.csv"]:
        shutil.copy(ROOT / "raw" / "example" / name, rec / name)
    return clean(_unshare_ro(rec, [PY, "-m", "spa", "init", str(rec)]), "Read-only file system")


@probe
def probe_ingest_read_only_output(tmp: Path) -> tuple[bool, str]:
    (tmp / "out").mkdir()
    res = _unshare_ro(tmp / "out", [PY, "-m", "spa", "ingest", str(ROOT / "raw" / "example"),
                                    str(tmp / "out")])  # fmt: skip
    ok, why = clean(res, "the output folder is not writable")
    blamed = "cannot read the file" in res.stdout or "0 data rows" in res.stdout
    return ok and not blamed, why + ("; blames the recordings" if blamed else "")


_VALVE = ["--c1", ".5", "--k2", ".8", "--tau2", ".8", "--t-on", "0", "--t-off", ".01"]
PROBES["tune_t_on_zero"] = lambda tmp: clean(sh([PY, "-m", "spa", "tune", *_VALVE]), "t_on = 0 s")


@probe
def probe_tune_negative_k2_bound(tmp: Path) -> tuple[bool, str]:
    values = {"c1": 0.5, "k2": 0.8, "tau2": 0.8, "t_on": 0.003, "t_off": 0.01}
    params = {k: {"value": v, "lo": v * 0.9, "hi": v * 1.1} for k, v in values.items()}
    params["k2"]["lo"] = -0.1
    (tmp / "params.yaml").write_text(json.dumps(params))
    return clean(sh([PY, "-m", "spa", "tune", str(tmp / "params.yaml")]), "k2: the 95 % interval")


for name, value, needle in [
    ("sweep_step_1e-7", "analytic={sweeps: {pwm: {start: 1, stop: 80, step: 1e-7}}}",
     "analytic.sweeps.pwm.step: 1e-07 gives 790,000,001 points"),
    ("n_xi_1e9", "analytic={n_xi: 1e9}", "analytic.n_xi: 1000000000 is greater than"),
    ("ranges_backwards", "tuning={ranges: {pwm: [50, 5]}}",
     "tuning.ranges.pwm: [50, 5]: the lower bound 50 is above the upper bound 5"),
]:  # fmt: skip

    def _g(tmp: Path, value: str = value, needle: str = needle) -> tuple[bool, str]:
        return clean(snakemake(tmp, value), needle)

    PROBES[f"config_{name}"] = _g


def _mat_probe(kind: str, needle: str) -> Probe:
    def run(tmp: Path) -> tuple[bool, str]:
        sys.path.insert(0, str(ROOT / "tests"))
        from file_writers import write_v5_zeros, write_v73_declared

        folder = tmp / "d"
        folder.mkdir()
        if kind == "v5":  # 1.5 GiB of zeros, about 1.6 MB on disk
            write_v5_zeros(folder / "run.mat", 3 * 2**26)
        else:  # 2^40 samples declared, a few kB on disk
            write_v73_declared(folder / "run.mat", 2**40)
        (folder / "dataset.yaml").write_text(
            "name: d\ndescription: x\norigin: bench\nrig: {}\n"
            "runs:\n- {id: c, kind: charge, file: run.mat}\n"
        )
        start = time.perf_counter()
        args = [PY, "-m", "spa", "validate", str(folder)]
        proc = subprocess.Popen(
            args, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        text = proc.stdout.read()  # to the end: the child has exited or closed its output
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own peak, not the campaign's
        code = os.waitstatus_to_exitcode(status)
        seconds = time.perf_counter() - start
        rss = usage.ru_maxrss / 1024
        size = (folder / "run.mat").stat().st_size
        ok = code == 1 and needle in text and "Traceback" not in text and rss < 400
        return ok, f"{size:,} B file: exit {code} in {seconds:.1f} s, peak RSS {rss:.0f} MB"

    return run


PROBES["mat_v5_1_5_GiB_of_zeros"] = _mat_probe("v5", "declares 1x201326592 double")
PROBES["mat_v73_declares_2_40_samples"] = _mat_probe("v73", "but the file has")


@probe
def probe_pressure_in_bar_declared_kpa(tmp: Path) -> tuple[bool, str]:
    import pandas as pd
    import yaml

    src, folder = ROOT / "raw" / "example", tmp / "barkpa"
    folder.mkdir()
    spec = yaml.safe_load((src / "dataset.yaml").read_text())
    spec["runs"] = [r for r in spec["runs"] if r["kind"] in ("charge", "discharge", "pulse")]
    spec["name"] = "barkpa"
    for r in spec["runs"]:
        df = pd.read_csv(src / r["file"])
        df["P_act_kPa"] = (df["P_act_kPa"] / 100).round(6)  # logged in bar, declared kPa
        df.to_csv(folder / r["file"], index=False)
    (folder / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    val = sh([PY, "-m", "spa", "validate", str(folder)])
    ident = sh([PY, "-m", "spa", "identify", str(folder)])
    needle = "pressure logged in bar but declared kPa?"
    ok = needle in val.stdout and needle in ident.stdout and "k2 = 0.0" in ident.stdout
    return ok, "warned in validate and identify" if ok else (val.stdout + ident.stdout)[-300:]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-k", default="", help="run only the probes whose name has this text")
    args = ap.parse_args()
    raw_before = tree_digest(ROOT / "raw")
    failed = []
    chosen = {k: v for k, v in PROBES.items() if args.k in k}
    for name, fn in chosen.items():
        with tempfile.TemporaryDirectory(prefix="spa-probe-") as tmp:
            try:
                ok, why = fn(Path(tmp))
            except subprocess.TimeoutExpired:
                ok, why = False, "timed out"
        if tree_digest(ROOT / "raw") != raw_before:
            ok, why = False, "raw/ CHANGED"
        print(f"{'ok  ' if ok else 'FAIL'} {name}: {why}", flush=True)
        if not ok:
            failed.append(name)
    if "tmp" in _SHARED:
        shutil.rmtree(_SHARED["tmp"], ignore_errors=True)
    print(f"{len(chosen)} probes, {len(failed)} failed{': ' + ', '.join(failed) if failed else ''}")
    return 1 if failed else 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(main())
