"""Plan a bench session from a prior valve and the bench's limits (``spa plan``), play it on
the board (:mod:`spa.plan.player`) and capture its stream into a dataset (``spa record``).

=================  ===========================================================
module             holds
=================  ===========================================================
``limits``         the bench's limits and the link's check
``prior``          the valve a plan is made for
``session``        runs as segments, and the commands they issue
``design``         the session's runs, holds, frequencies, replicates, order
``player``         the C99 player header, host harness and sketch
``folder``         the plan's folder: plan.yaml, dataset.yaml, checklist, player
``record``         the board's stream split into the plan's run files
``host``           the player compiled on the host and closed on a plant (physical or model)
``precision``      the predicted precision, and the runs resized to meet its targets
``budget``         a bench-time budget, what a plan gives up for it, a missed target
``verify``         a verification session: its runs and predictions
``bands``          a prediction's 95 % band: the identification's draws, model error, noise
``verify_error``   the model's held-out error, measured on the dataset's own runs
``loop_bands``     the closed loop's measures predicted on draws, with two-ended bands
``verdicts``       a recording measured, each prediction kept or broken, the session's verdict
``verify_command`` ``spa plan --verify``: the plan.yaml predictions; the recorded comparison
``drift``          the drifts each kind of a verification's predictions can detect
``roundtrip``      a recorded session's stages and its verification played on a plant
=================  ===========================================================
"""

from spa.plan.design import SessionDesign, design_session
from spa.plan.limits import Limits, PlanError
from spa.plan.session import PlannedRun, Segment

__all__ = ["Limits", "PlanError", "PlannedRun", "Segment", "SessionDesign", "design_session"]
