"""The run as one object: its folder (:mod:`~experiments.runs.folder`), what it records
(:mod:`~experiments.runs.provenance`), its finished trials (:mod:`~experiments.runs.trials`),
signals (:mod:`~experiments.runs.signals`) and how it ends badly
(:mod:`~experiments.runs.failure`)."""
