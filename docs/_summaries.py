"""Where the API reference's one-line summaries may not end: after an abbreviation.

Sphinx's autosummary takes a docstring's first sentence, cutting at the first full stop
followed by a space unless the text so far ends in one of
``sphinx.ext.autosummary.WELL_KNOWN_ABBREVIATIONS`` ("e.g.", "i.e.", ...). spa's docstrings
cite the paper as "(Eq. 5)", "(App. B)" and "(Table 3, Figs. 6-7)": without these the summary
stops at "(Eq.".
"""

from __future__ import annotations

#: The paper's abbreviations that a docstring's first sentence uses.
ABBREVIATIONS: tuple[str, ...] = ("Eq.", "Eqs.", "App.", "Fig.", "Figs.", "Sec.", "Ref.")


def extend_abbreviations() -> tuple[str, ...]:
    """Add :data:`ABBREVIATIONS` to autosummary's list (once); return the whole list."""
    from sphinx.ext import autosummary

    known = tuple(autosummary.WELL_KNOWN_ABBREVIATIONS)
    autosummary.WELL_KNOWN_ABBREVIATIONS = known + tuple(a for a in ABBREVIATIONS if a not in known)
    return autosummary.WELL_KNOWN_ABBREVIATIONS
