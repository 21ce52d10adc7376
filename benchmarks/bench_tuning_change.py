"""What a ``tuning:`` change costs over processed datasets, against their cold run: one tree.

Run from the repository root:

    nice .venv/bin/python benchmarks/bench_tuning_change.py --count 18 [--figures] [--tree T]

`snakemake reproduce-all -c2` of the small configuration over raw/example, ``--count``
example benches of their own noise seeds (``python -m spa example --seed``, so that no result
is shared between datasets) and the config's `sim`, cold; then the same with
``tuning: {max_chattering: 0.04}``. Prints the wall and CPU time of each (Snakemake and every
job, ``os.wait4``), the ratio, the peak RSS, and each stage's CPU in two added datasets'
analysis jobs (``SPA_PROFILE_DIR``). ``--figures`` draws every figure (the default of a run);
without it, ``figures: none``. The side-by-side version against an old tree is
``bench_side_by_side.py --processed``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_side_by_side as side


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", type=Path, default=side.ROOT, help="the checkout to time")
    parser.add_argument("--count", type=int, default=18, help="seeded benches besides example")
    parser.add_argument("--figures", action="store_true", help="draw every figure")
    parser.add_argument("--keep", type=Path, help="work here and keep the results (empty)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="tuning_change_") as tmp_name:
        work = args.keep.resolve() if args.keep else Path(tmp_name)
        raw = side.seeded(work / "raw", args.count)
        out = work / "res"
        extra = "" if args.figures else "figures: none\n"
        times = {}
        for step, more in (("cold", extra), ("tuning", extra + side.TUNING_CHANGE)):
            cfg = side.config(work, raw, out, more)
            times[step] = side.run(args.tree.resolve(), cfg, work / f"prof_{step}")
            wall, cpu, peak = times[step]
            print(f"{step}: wall {wall:.1f} s, CPU {cpu:.1f} s, peak RSS {peak:.0f} MiB")
            for d in ("bench000", "bench001"):
                per = side.stage_cpu(work / f"prof_{step}", [d])
                print(f"  {d}: " + ", ".join(f"{k} {v:.2f}" for k, v in sorted(per.items())))
    (cw, cc, _), (tw, tc, _) = times["cold"], times["tuning"]
    print(f"\ntuning change / cold run over {args.count + 2} datasets: "
          f"{tw / cw:.0%} wall, {tc / cc:.0%} CPU")  # fmt: skip


if __name__ == "__main__":
    main()
