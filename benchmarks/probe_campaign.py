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
    "v = spa.ValveParams(c1=0.45, k2=1.05, tau2=0.70, t_on=0.004, t_off=0.009)\n"
    "t = tune(v).table2.set_index('modulator')\n"
    "s = {k: r.optimum_exact * (1 if k == 'pwm' else 1e-3) for k, r in t.iterrows()}\n"
    "c = {k: float(setting_metrics(k, x, v)['chattering']) for k, x in s.items()}\n"
    "edge = t[['optimum_at_grid_edge', 'optimum_exact_at_grid_edge']].any().any()\n"
    "bad = max(c.values()) > 0.05 or edge\n"
    "print(('FAIL ' if bad else 'ok ') + str(dict(t.optimum_exact)) + ' chattering ' + str(c))"
)
PROBES["chirp_reference_through_the_runs_sensor"] = numbers(
    "from spa.openloop import chirp_reference, no_ringing_spread\n"
    "from spa.synthetic import generate_dataset\n"
    "from spa.io import read_runs\n"
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
    print(f"{len(chosen)} probes, {len(failed)} failed{': ' + ', '.join(failed) if failed else ''}")
    return 1 if failed else 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(main())
