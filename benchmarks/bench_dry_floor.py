"""The dry run over many datasets against Snakemake's own floor for a DAG of the same shape.

Run from the repository root (nothing is written to results/ or raw/):

    .venv/bin/python benchmarks/bench_dry_floor.py --count 101 --repeat 5

``--count`` renamed copies of raw/example plus the simulated dataset ``sim`` (102 datasets
with 101) go into a temporary raw folder, and two dry runs are timed alternately, from an
empty results folder (nothing processed yet):

- spa: `snakemake reproduce-all --dry-run` with the small configuration;
- floor: a generated Snakefile with the same jobs and the same files, each rule's
  ``output:`` the workflow's (spa.pipeline.outputs: the analysis job of each dataset, its
  ingest or simulation, the four analytic rules, overview, report, check, reproduce-all),
  every job ``touch``, no parameters, no imports: what Snakemake itself costs to build that
  DAG.

Prints the wall time (min and median) and the CPU time of each (user + system, min).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def floor_snakefile(folder: Path, results: Path, raw_names: list[str]) -> Path:
    """A trivial Snakefile with the jobs and files of `reproduce-all` for ``sim`` and
    ``raw_names``, nothing processed yet."""
    from spa.pipeline.jobs import joined_outputs
    from spa.pipeline.outputs import STAGES, all_targets, job_stages, log_path, stage_outputs

    res = str(results)

    def outs(stage: str, dataset: str = "{dataset}") -> dict[str, str]:
        return {k: str(v) for k, v in stage_outputs(stage, res, dataset).items()}

    def block(paths: dict[str, str]) -> str:
        lines = []
        for key, path in paths.items():
            directory = not Path(path).suffix
            lines.append(f"        {key}={'directory(' if directory else ''}{path!r}"
                         f"{')' if directory else ''},")  # fmt: skip
        return "\n".join(lines)

    def logs(*rules: str) -> str:
        return "    log:\n" + "\n".join(f"        {r}={log_path(r, res)!r}," for r in rules) + "\n"

    datasets = ["sim", *raw_names]
    analyse = joined_outputs(job_stages("analyse"), outs)
    ingest = joined_outputs(job_stages("ingest"), outs)
    text = [f"RAW = {raw_names!r}", "SIM = ['sim']", f"DATASETS = {datasets!r}", ""]
    text.append("rule all:\n    input:\n" + block(outs("check")) + "\n")
    for stage in [s.name for s in STAGES if s.name.startswith("analytic_")]:
        text.append(f"rule {stage}:\n    output:\n{block(outs(stage))}\n{logs(stage)}"
                    "    shell: 'touch {output}'\n")  # fmt: skip
    text.append(
        "rule simulate:\n    output:\n"
        + block(outs("runs"))
        + "\n"
        + logs("simulate_dataset")
        + "    wildcard_constraints: dataset='|'.join(SIM)\n    shell: 'touch {output}'\n"
    )
    text.append(
        "rule ingest:\n    output:\n"
        + block(ingest)
        + "\n"
        + logs("raw_manifest", "ingest_dataset")
        + "    wildcard_constraints: dataset='|'.join(RAW)\n    shell: 'touch {output}'\n"
    )
    runs = outs("runs")
    text.append(
        "rule analyse:\n    input:\n"
        + block(runs)
        + "\n    output:\n"
        + block(analyse)
        + "\n"
        + logs(*job_stages("analyse"))
        + "    shell: 'touch {output}'\n"
    )
    rows = stage_outputs("page", res)["row"]
    text.append(
        f"rule overview:\n    input: expand({str(rows)!r}, dataset=DATASETS)\n"
        f"    output:\n{block(outs('overview'))}\n{logs('overview')}    shell: 'touch {{output}}'\n"
    )
    report_inputs = all_targets(res, datasets, exclude=["report", "check"])
    text.append(
        f"rule report:\n    input: {report_inputs!r}\n    output:\n{block(outs('report'))}\n"
        + logs("report")
        + "    shell: 'touch {output}'\n"
    )
    text.append(
        f"rule check:\n    input:\n{block(outs('report'))}\n    output:\n{block(outs('check'))}\n"
        + logs("check")
        + "    shell: 'touch {output}'\n"
    )
    path = folder / "Snakefile"
    path.write_text("\n".join(text))
    return path


def timed(args: list[str], cwd: Path, env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU time (user + system) of a command; exits with its output on failure."""
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as log:
        proc = subprocess.Popen(args, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        if os.waitstatus_to_exitcode(status) != 0:
            log.seek(0)
            sys.exit(f"{' '.join(args)} failed:\n{log.read()[-3000:]}")
    return wall, usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=101)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--tree", type=Path, default=ROOT, help="the spa tree to time")
    args = ap.parse_args()
    env = {**os.environ, "PYTHONPATH": str(args.tree)}
    smk = [sys.executable, "-m", "snakemake"]
    with tempfile.TemporaryDirectory(prefix="spa-floor-") as tmp:
        raw, results = Path(tmp) / "raw", Path(tmp) / "results"
        names = [f"bench{i:03d}" for i in range(args.count)]
        for name in names:
            shutil.copytree(ROOT / "raw" / "example", raw / name)
            spec = raw / name / "dataset.yaml"
            spec.write_text(spec.read_text().replace("name: example", f"name: {name}"))
        floor_dir = Path(tmp) / "floor"
        floor_dir.mkdir()
        floor_snakefile(floor_dir, results, names)
        cfg = Path(tmp) / "raw.yaml"
        cfg.write_text(f"datasets:\n  raw_dir: {raw}\n  include: []\n  exclude: []\n")
        spa_cmd = [*smk, "reproduce-all", "-n", "--configfile", "config/small.yaml", str(cfg),
                   "--config", f"results={results}"]  # fmt: skip
        floor_cmd = [*smk, "-n", "-c1", "--snakefile", str(floor_dir / "Snakefile")]
        times: dict[str, list[tuple[float, float]]] = {"spa": [], "floor": []}
        timed(spa_cmd, args.tree, env)  # the raw digests cached, as after a first run
        for _ in range(args.repeat):
            times["floor"].append(timed(floor_cmd, floor_dir, env))
            times["spa"].append(timed(spa_cmd, args.tree, env))
    load = os.getloadavg()
    print(f"{args.count + 1} datasets, dry run from an empty results folder, "
          f"{args.repeat} runs each, load average {load[0]:.1f}")  # fmt: skip
    print("| dry run | wall min (s) | wall median (s) | CPU min (s) |")
    print("|---|---:|---:|---:|")
    for name, values in times.items():
        walls, cpus = [w for w, _ in values], [c for _, c in values]
        print(f"| {name} | {min(walls):.2f} | {statistics.median(walls):.2f} | {min(cpus):.2f} |")


if __name__ == "__main__":
    main()
