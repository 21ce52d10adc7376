"""Errors the science raises and the pipeline sorts: a run's, or the machine's.

At the bottom of the import graph: the analyses (``spa.openloop``, ``spa.datasets``) raise
and test these, and :mod:`spa.pipeline.status` decides what a failure costs.
"""

from __future__ import annotations

import errno

__all__ = ["ENVIRONMENT_ERRNOS", "RunError"]

#: ``errno`` values that say the machine, not the data, stopped a stage.
ENVIRONMENT_ERRNOS = frozenset(
    {errno.ENOSPC, errno.EFBIG, errno.EROFS, errno.EDQUOT, errno.ENOMEM, errno.EMFILE}
)


class RunError(ValueError):
    """An analysis of one run failed; the message names the run and its kind."""
