"""Pair two physical-plant benchmark tables plant by plant: before and after a change.

Reads CSVs of ``benchmarks/physical_plants.py --promise`` (the same ``--n`` and ``--seed``
on both sides: the same plants, drawn by ``random_plant`` from ``[seed, index]``), pairs the
rows by seed and plant index, and prints per seed, before -> after:

- the held-out staircase FIT, median over plants of each plant's median
  (``heldout_median_fit``), over every plant and over the compliant low-supply ones (supply
  <= 0.8 bar and volume growth >= 100 %/bar, ``spa.synthetic.balloons.compliant_low_supply``;
  recomputed from the ``plant_*`` columns when a table lacks ``compliant_low_supply``), and
  the paired median difference (the median over plants of after minus before);
- the unverified plants (``verified`` false), and the verified promises broken on the plant
  in C (``verified`` and not ``kept``), with their plant indices;
- how many plants chose the actuator's own laws (``laws == identified``; a table without the
  column chose the paper's everywhere).

The Done-when of issue 47 (the actuator's own laws): the FIT improves, by at least 10 points
median on the compliant low-supply plants; at most 1 plant per seed unverified; no verified
promise broken.

Run:  .venv/bin/python benchmarks/physical_pair.py BEFORE_S1.csv AFTER_S1.csv
      [BEFORE_S2.csv AFTER_S2.csv ...]
A table's seed is its ``seed`` column, else the ``-s<N>`` of its file name.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from spa.synthetic.balloons import compliant_low_supply

#: What the Done-when asks of the compliant low-supply plants' paired median gain, points.
COMPLIANT_GAIN = 10.0


def read_table(path: Path) -> pd.DataFrame:
    """One benchmark table with ``seed``, ``plant``, ``compliant_low_supply``, ``verified``,
    ``kept``, ``laws`` and ``heldout_median_fit`` (filled in where an older table lacks
    them).

    Raises
    ------
    ValueError
        If the table has no ``plant`` column, or no seed (column or ``-s<N>`` in its name).
    """
    table = pd.read_csv(path)
    if "plant" not in table:
        raise ValueError(f"{path}: no 'plant' column: not a physical_plants.py table")
    if "seed" not in table:
        found = re.search(r"-s(\d+)", path.stem)
        if found is None:
            raise ValueError(f"{path}: no 'seed' column and no '-s<N>' in the file name")
        table["seed"] = int(found.group(1))
    if "compliant_low_supply" not in table:
        for col in ("plant_supply", "plant_volume", "plant_compliance"):
            if col not in table:
                raise ValueError(f"{path}: neither 'compliant_low_supply' nor '{col}'")
        table["compliant_low_supply"] = compliant_low_supply(
            table["plant_supply"], table["plant_volume"], table["plant_compliance"]
        )
    for col, default in (("verified", False), ("kept", False), ("laws", "paper")):
        if col not in table:
            table[col] = default
    if "heldout_median_fit" not in table:
        table["heldout_median_fit"] = math.nan
    table["verified"] = table["verified"].fillna(False).astype(bool)
    table["kept"] = table["kept"].fillna(False).astype(bool)
    table["laws"] = table["laws"].fillna("paper")
    table["compliant_low_supply"] = table["compliant_low_supply"].astype(bool)
    return table.copy()


def pair(before: pd.DataFrame, after: pd.DataFrame) -> pd.DataFrame:
    """The plants of both tables, one row each, columns suffixed ``_before``/``_after``.

    Raises
    ------
    ValueError
        If the two tables' plants differ (another ``--n``, or a plant drawn differently).
    """
    keys = ["seed", "plant"]
    both = before.merge(after, on=keys, how="outer", suffixes=("_before", "_after"))
    both = both.copy()  # one block: the merge leaves it fragmented
    one_side = set(map(tuple, before[keys].to_numpy())) ^ set(map(tuple, after[keys].to_numpy()))
    if one_side:
        raise ValueError(f"plants (seed, index) in one table only: {sorted(one_side)}")
    for col in ("plant_supply", "plant_volume"):
        if f"{col}_before" in both and f"{col}_after" in both:
            differ = ~np.isclose(both[f"{col}_before"], both[f"{col}_after"], rtol=1e-12)
            if differ.any():
                bad = both.loc[differ, keys].to_numpy().tolist()
                raise ValueError(
                    f"{col} differs between the tables for plants {bad}: not the same draws"
                )
    both = both.assign(compliant_low_supply=both["compliant_low_supply_before"])
    return both.sort_values(keys).reset_index(drop=True)


def summary(paired: pd.DataFrame) -> pd.DataFrame:
    """Per seed: the medians, paired differences and counts the module docstring lists."""
    rows = []
    for seed, g in paired.groupby("seed"):
        row: dict = {"seed": int(seed), "plants": len(g)}
        for name, sel in (("all", g), ("compliant", g[g["compliant_low_supply"]])):
            b, a = sel["heldout_median_fit_before"], sel["heldout_median_fit_after"]
            d = (a - b).dropna()
            row[f"{name}_n"] = len(sel)
            row[f"{name}_fit_before"] = float(b.median()) if len(sel) else math.nan
            row[f"{name}_fit_after"] = float(a.median()) if len(sel) else math.nan
            row[f"{name}_paired_median_diff"] = float(d.median()) if len(d) else math.nan
        for side in ("before", "after"):
            unver = g[~g[f"verified_{side}"]]
            broken = g[g[f"verified_{side}"] & ~g[f"kept_{side}"]]
            row[f"unverified_{side}"] = len(unver)
            row[f"unverified_{side}_plants"] = unver["plant"].tolist()
            row[f"broken_{side}"] = len(broken)
            row[f"broken_{side}_plants"] = broken["plant"].tolist()
            row[f"laws_identified_{side}"] = int((g[f"laws_{side}"] == "identified").sum())
        rows.append(row)
    return pd.DataFrame(rows)


def report(s: pd.Series) -> str:
    """The lines printed for one seed, with the Done-when's verdicts."""
    c_gain = s["compliant_paired_median_diff"]
    return "\n".join(
        [
            f"seed {s['seed']}: {s['plants']} plants, {s['compliant_n']} compliant low-supply",
            f"  held-out staircase FIT median, all plants: {s['all_fit_before']:.1f} -> "
            f"{s['all_fit_after']:.1f} %, paired median difference "
            f"{s['all_paired_median_diff']:+.1f} points "
            f"({'improves' if s['all_paired_median_diff'] > 0 else 'does not improve'})",
            f"  compliant low-supply: {s['compliant_fit_before']:.1f} -> "
            f"{s['compliant_fit_after']:.1f} %, paired median difference {c_gain:+.1f} points "
            f"({'met' if c_gain >= COMPLIANT_GAIN else 'not met'}: >= {COMPLIANT_GAIN:g})",
            f"  unverified: {s['unverified_before']} {s['unverified_before_plants']} -> "
            f"{s['unverified_after']} {s['unverified_after_plants']} "
            f"({'met' if s['unverified_after'] <= 1 else 'not met'}: <= 1)",
            f"  verified promises broken on the plant in C: {s['broken_before']} "
            f"{s['broken_before_plants']} -> {s['broken_after']} {s['broken_after_plants']} "
            f"({'met' if s['broken_after'] == 0 else 'not met'}: 0)",
            f"  laws chosen identified: {s['laws_identified_before']} -> "
            f"{s['laws_identified_after']}",
        ]
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tables", nargs="+", type=Path, help="BEFORE AFTER [BEFORE AFTER ...]")
    ap.add_argument("--csv", type=Path, default=None, help="the per-seed summary")
    args = ap.parse_args(argv)
    if len(args.tables) % 2:
        ap.error("give the tables in pairs: BEFORE AFTER [BEFORE AFTER ...]")
    paired = pd.concat(
        [
            pair(read_table(b), read_table(a))
            for b, a in zip(args.tables[::2], args.tables[1::2], strict=True)
        ],
        ignore_index=True,
    )
    table = summary(paired)
    for _, s in table.iterrows():
        print(report(s))
    if args.csv is not None:
        table.to_csv(args.csv, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
