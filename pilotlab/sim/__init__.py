"""The driving simulator: a pybullet world with the circuit's road, a car, its camera, drivers, recording.

Start with `pilotlab.sim.env.DrivingEnv` (docs/simulator.md has the tour).
"""
