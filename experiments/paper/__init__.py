"""The paper's experiments (``wander experiment NAME``), their analyses and ``configs/``."""
