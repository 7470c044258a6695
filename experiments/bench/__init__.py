"""Speed benchmarks (``wander bench ...``): env, DVS emulator, agent, fidelity, formats."""
