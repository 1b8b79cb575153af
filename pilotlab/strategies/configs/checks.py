"""Range checks the strategy configs share, run in their `__post_init__` (so a bad option is an
error when the recipe is read, not when the job runs)."""
from __future__ import annotations

from pilotlab.errors import PilotlabError


def check_fraction(option: str, value: float) -> None:
    if not 0.0 <= value < 1.0:
        raise PilotlabError(f"{option}: {value} is not a fraction in [0, 1)")


def check_distill(distill: float) -> None:
    if not 0.0 <= distill <= 1.0:
        raise PilotlabError(f"distill: {distill} is not a weight in [0, 1] (0: the labels alone, 1: the trained "
                            "baseline's outputs alone)")


def check_multiple(multiple_of: int) -> None:
    if multiple_of < 1:
        raise PilotlabError(f"multiple_of: {multiple_of} must be an integer ≥ 1")


def check_subsample(subsample_stem: int) -> None:
    if subsample_stem < 0:
        raise PilotlabError(f"subsample_stem: {subsample_stem} must be an integer ≥ 0 (how many of the first "
                            "convolutions run at twice their stride; 0: none)")


def check_clusters(clusters: int) -> None:
    if not 2 <= clusters <= 256:
        raise PilotlabError(f"clusters: {clusters} must be between 2 and 256 (int8 has 256 values)")
