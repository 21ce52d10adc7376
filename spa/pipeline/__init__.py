"""The workflow's plumbing, below the science in the import graph.

The modules here wire :mod:`spa`'s analyses into the Snakemake pipeline and never hold
science of their own:

* :mod:`~spa.pipeline.config`: checking the configuration and choosing the datasets;
* :mod:`~spa.pipeline.stage_types` and :mod:`~spa.pipeline.outputs`: what each stage writes
  (the one registry the rules, ``reproduce-all`` and the report read);
* :mod:`~spa.pipeline.jobs`: several stages of a dataset in one Snakemake job;
* :mod:`~spa.pipeline.status`: one bad dataset costs only itself; environment errors fail
  the job instead;
* :mod:`~spa.pipeline.provenance`: content digests of what a result was made from;
* :mod:`~spa.pipeline.safety`: nothing writes under ``raw/``;
* :mod:`~spa.pipeline.workflow_report`: what ``snakemake --report`` shows.

Science modules (``spa.model``, ``spa.identification``, ``spa.tuning``, ...) do not import
this package.
"""
