"""Studies: many trials of a job, stored as they finish. An experiment
(:mod:`~experiments.studies.framework`: registry, config, trials, results folder) and a
sweep over a grid of them (:mod:`~experiments.studies.sweep`, local processes or Ray).
The report over finished results compares them with the paper, so it lives with the
paper's experiments (:mod:`experiments.paper.report`)."""
