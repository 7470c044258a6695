"""Analysis of finished trials, free of simulation: statistics with confidence intervals
(:mod:`~experiments.analysis.stats`), scanpath statistics
(:mod:`~experiments.analysis.scanpath_stats`) and a run's metrics
(:mod:`~experiments.analysis.metrics`)."""
