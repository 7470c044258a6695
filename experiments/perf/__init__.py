"""Speed benchmarks (``wander perf ...``): env, DVS emulator, agent, fidelity, formats."""
