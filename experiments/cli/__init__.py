"""The ``wander`` command line (the top floor): :mod:`experiments.cli.main` builds the app."""
