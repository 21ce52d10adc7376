"""The figures the READMEs quote, rendered from the benchmarks' CSVs in the repository.

A quoted figure is marked in the Markdown as ``<!-- fig NAME -->VALUE<!-- /fig -->`` (the
comments do not show on a rendered page). ``NAME`` is a key of :data:`FIGURES`: a CSV under
``benchmarks/results/`` and the function that computes the figure from it, rounded as the
text states it. ``--check`` fails, naming the file, line and figure, when a marked value is
not what its CSV gives (a number edited by hand, or a CSV re-measured without the text) or
when a marker names no figure; ``--write`` renders every marked value from its CSV.

    .venv/bin/python benchmarks/figures.py --check    # README.md and benchmarks/README.md
    .venv/bin/python benchmarks/figures.py --write
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from functools import cache
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
#: The Markdown files whose marked figures are checked.
DOCUMENTS = (ROOT / "README.md", ROOT / "benchmarks" / "README.md")

MARKER = re.compile(r"<!-- fig (?P<name>[\w.:%-]+) -->(?P<value>.*?)<!-- /fig -->")


@cache
def _csv(name: str) -> pd.DataFrame:
    return pd.read_csv(RESULTS / name)


def _coverage(valve: str) -> pd.DataFrame:
    return _csv(f"verification_coverage_{valve}.csv")


def _kept_percent(valve: str, arm: str) -> str:
    g = _coverage(valve)[lambda f: f["arm"] == arm]
    return f"{100.0 * g['kept'].sum() / g['predictions'].sum():.1f}"


def _sessions_broken(valve: str, arm: str) -> str:
    g = _coverage(valve)[lambda f: f["arm"] == arm]
    return str(int(((g["outside_session"] + g["promise_outside_session"]) > 0).sum()))


def _unseen(arm: str) -> pd.DataFrame:
    return _csv("verify_round_trip_unseen.csv")[lambda f: f["verified_on"] == arm]


def _unseen_sessions(arm: str) -> str:
    g = _unseen(arm)
    return f"{int(g['session_broken'].sum())} of {len(g)}"


def _unseen_promise_broken(arm: str) -> str:
    g = _unseen(arm)
    return f"{int((g['promise_kept'] < g['promise_n']).sum())} of {len(g)}"


def _unseen_kept(arm: str, part: str) -> str:
    g = _unseen(arm)
    return f"{int(g[f'{part}_kept'].sum())} of {int(g[f'{part}_n'].sum())}"


def _unseen_overlap(name: str) -> str:
    g = _unseen("same")
    return f"{int(g[f'{name}_overlap'].sum())} of {len(g)}"


def _unseen_levels() -> str:
    g = _unseen("same")
    return f"{int((g['promise_levels'] >= 3).sum())} of {len(g)}"


_ARMS = {
    "same": "same",
    "slower": "2x slower",
    "exhaust": "exhaust halved",
    "supply": "supply -20%",
}

#: Figure name -> the function that renders it from its CSV.
FIGURES: dict[str, Callable[[], str]] = {
    **{
        f"coverage.{v}.{a}.kept_percent": (lambda v=v, a=a: _kept_percent(v, a))
        for v in ("small-fast", "long-exhaust")
        for a in ("same", "2x slower")
    },
    **{
        f"coverage.{v}.{a}.sessions_broken": (lambda v=v, a=a: _sessions_broken(v, a))
        for v in ("small-fast", "long-exhaust")
        for a in ("same", "2x slower")
    },
    **{f"unseen.{k}.sessions_broken": (lambda a=a: _unseen_sessions(a)) for k, a in _ARMS.items()},
    **{
        f"unseen.{k}.promise_broken": (lambda a=a: _unseen_promise_broken(a))
        for k, a in _ARMS.items()
    },
    **{
        f"unseen.{k}.{part}_kept": (lambda a=a, part=part: _unseen_kept(a, part))
        for k, a in _ARMS.items()
        for part in ("recommendation", "promise")
    },
    "unseen.promise_three_levels": _unseen_levels,
    **{
        f"unseen.{n}_overlap": (lambda n=n: _unseen_overlap(n))
        for n in ("c1", "k2", "tau2", "t_on", "t_off")
    },
}


def problems(text: str, where: str = "text") -> list[str]:
    """Each marked figure of ``text`` that is not what its CSV gives, or names no figure:
    ``"<where>:<line>: <name> reads <value>, its CSV gives <figure>"``."""
    out = []
    for m in MARKER.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        name, value = m["name"], m["value"]
        if name not in FIGURES:
            out.append(f"{where}:{line}: {name} is no figure of benchmarks/figures.py")
            continue
        figure = FIGURES[name]()
        if value != figure:
            out.append(f"{where}:{line}: {name} reads {value!r}, its CSV gives {figure!r}")
    return out


def render(text: str) -> str:
    """``text`` with every marked figure rendered from its CSV (unknown names left)."""

    def one(m: re.Match[str]) -> str:
        name = m["name"]
        value = FIGURES[name]() if name in FIGURES else m["value"]
        return f"<!-- fig {name} -->{value}<!-- /fig -->"

    return MARKER.sub(one, text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="fail on a figure not its CSV's")
    mode.add_argument("--write", action="store_true", help="render the figures from the CSVs")
    args = ap.parse_args(argv)
    found = []
    for doc in DOCUMENTS:
        text = doc.read_text(encoding="utf-8")
        if args.write:
            doc.write_text(render(text), encoding="utf-8")
        else:
            found += problems(text, str(doc.relative_to(ROOT)))
    for line in found:
        print(line, file=sys.stderr)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
