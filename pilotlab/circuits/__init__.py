"""Circuits: the red line to follow, the road around it, and the registry of known circuits."""
from pilotlab.circuits.circuit import DIRECTIONS, Circuit, Projection, wrap_angle
from pilotlab.circuits.registry import (CIRCUITS, CircuitConfig, all_circuit_names, csv_path_of, get_circuit,
                                        read_points_csv, user_circuits, user_dirs)

__all__ = ["CIRCUITS", "DIRECTIONS", "Circuit", "CircuitConfig", "Projection", "all_circuit_names",
           "csv_path_of", "get_circuit", "read_points_csv", "user_circuits", "user_dirs", "wrap_angle"]
