"""Jobs: one run of the agent, an evaluation, a rig run, a recording (and their run logs)."""
