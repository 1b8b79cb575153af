"""Circuits: the red line to follow, the road around it, and the registry of known circuits.

This package's names are the registry's (which circuits there are and where their CSVs lie), which
planning imports: they need no numpy. The circuit itself, its geometry and its loading are in
`pilotlab.circuits.circuit` (Circuit, Projection, DIRECTIONS) and `pilotlab.circuits.load`
(get_circuit, read_points_csv).
"""
from pilotlab.circuits.registry import CIRCUITS, CircuitConfig, all_circuit_names, csv_path_of, user_circuits, user_dirs

__all__ = ["CIRCUITS", "CircuitConfig", "all_circuit_names", "csv_path_of", "user_circuits", "user_dirs"]
