"""A verification session's section of its dataset's page: each prediction spa made for the
verified dataset beside what the bench then measured (``spa plan --verify``, recorded by
``spa record``, which writes the comparison as the session folder's ``verification.csv``).

The section is self-contained: :func:`verification_html` renders it from that file alone, in
two parts, the recommendation (each staircase level and the FIT) and the promise (the
closed loop's overshoot, settling and ripple), each row "kept" or "broken by <amount>".
"""

from __future__ import annotations

import html
from pathlib import Path

import pandas as pd

from spa.report.html import html_table, unique_anchor

__all__ = ["VERIFICATION_FILE", "verification_html"]

#: The comparison ``spa record`` writes into a verification session's folder.
VERIFICATION_FILE = "verification.csv"

_PARTS = {
    "recommendation": (
        "Verification: the recommendation",
        "The recommended setting's staircases and sines on the bench: each level's mean "
        "pressure over the second half of its hold and the staircase's FIT, each sine's mean "
        "and fundamental's amplitude over its second half, against the prediction on the "
        "identified valve. The 95 % band holds one measurement of an unchanged plant 95 times "
        "in 100: t times the root sum of squares of the prediction's spread over valves drawn "
        "from the identification's uncertainty, the model's held-out error measured on the "
        "dataset's own staircases and sines (plan.yaml: verify.model_error; the worst recorded "
        "setting's when this one was not recorded: extrapolated) and the sensor's noise on the "
        "measurement. About one prediction in twenty breaks by chance; the session is broken "
        "when one leaves its band at the session level (column session: outside), designed "
        "for an unchanged plant to do once in twenty sessions (measured 7-16 % on spa's "
        "model valves).",
    ),
    "promise": (
        "Verification: the closed loop's promise",
        "The closed_loop stage's controller, played through its controller.h on the bench over "
        "the promise's staircase (levels up then down, after one hold at the first): its worst "
        "overshoot and settling time on the cycle-mean pressure (each step's settling on its "
        "own samples, past what the sensor adds to the cycle-mean) and its worst peak-to-peak "
        "ripple of the logged pressure, against the prediction: the same staircase simulated "
        "through the same PI and modulator on valves drawn from the identification's "
        "uncertainty, each with the sensor's noise, measured the same way (95 % prediction "
        "interval of the draws; both ends can break). Kept: the measurement lies in its band.",
    ),
}

_COLUMNS = ["part", "run", "prediction", "predicted", "band", "measured", "verdict"]


def verification_html(
    path: str | Path, taken: set[str], prefix: str = "dataset"
) -> tuple[str, list[tuple[str, str]]]:
    """The section's HTML and its table-of-contents entries ("" and none without the file).

    Parameters
    ----------
    path : str or Path
        A verification session's ``verification.csv``.
    taken : set of str
        Anchors already used on the page (extended with this section's).
    prefix : str, default "dataset"
        Prefix of the anchors.

    Raises
    ------
    ValueError
        If the file lacks a column (naming the file and the columns expected).
    """
    from spa.plan.verify import session_verdict

    p = Path(path)
    if not p.is_file():
        return "", []
    table = pd.read_csv(p, keep_default_na=False, na_values=[""])
    missing = [c for c in _COLUMNS if c not in table.columns]
    if missing:
        raise ValueError(f"{p}: no column {missing}; expected {_COLUMNS} (spa record writes it)")
    parts, toc = [], []
    for part, (title, caption) in _PARTS.items():
        rows = table[table["part"] == part]
        kept = int((rows["verdict"] == "kept").sum())
        anchor = unique_anchor(f"{prefix}-verification-{part}", taken)
        heading = f"{title}: {kept} of {len(rows)} predictions kept"
        said = session_verdict(table, None) if part == "recommendation" else ""
        body = (
            html_table(rows.drop(columns="part").reset_index(drop=True))
            if len(rows)
            else "No run of this part recorded, or no prediction made."
        )
        parts.append(
            f'<figure id="{anchor}">\n<h3>{html.escape(heading)}</h3>\n'
            + (f"<p>{html.escape(said)}</p>\n" if said else "")
            + f'<div class="scroll">{body}</div>\n'
            f"<figcaption>{html.escape(caption)}</figcaption>\n</figure>\n"
        )
        toc.append((anchor, heading))
    return "".join(parts), toc
