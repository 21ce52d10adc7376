"""Each open-loop stage of a dataset's analysis as two functions: ``run_<stage>`` computes
its tables from its inputs (:class:`spa.stages._common.OpenLoopInputs`: the run tables and
their metadata, the identified valve, the stage's settings; pure: no file is read or written)
and ``write_<stage>`` writes them and draws its figures to the paths the workflow gives.

The workflow's scripts (``workflow/scripts/<stage>.py``) only read the inputs, call these and
log; a notebook can call the same functions on its own run tables.

* :mod:`spa.stages.staircase`: Table 3, Figs. 6, 7a and 7b (paper Section 6.1);
* :mod:`spa.stages.sine`: the sine table and Fig. 8 (Section 6.2);
* :mod:`spa.stages.chirp`: the bicoherence table and Fig. 9 (Section 6.3).

The other stages' functions live with their science: :func:`spa.identification.identify`,
:func:`spa.tuning.tune`, :func:`spa.validation.validate_runs`,
:func:`spa.closedloop.comparison.closed_loop`.
"""
