"""Tiny circuits for fast tests: real CSV files the circuit registry reads like any user circuit."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def stadium(length: float = 30.0, radius: float = 8.0, spacing: float = 0.2) -> np.ndarray:
    """Points of a clockwise stadium: two straights of `length` joined by half circles of `radius`
    (lap = 2 * length + 2 * pi * radius), starting at the middle of the top straight, heading east."""
    straight = np.arange(0.0, length, spacing)
    turn = np.arange(0.0, np.pi, spacing / radius)
    top = np.stack([straight - length / 2, np.full_like(straight, radius)], axis=1)
    right = np.stack([length / 2 + radius * np.sin(turn), radius * np.cos(turn)], axis=1)
    bottom = np.stack([length / 2 - straight, np.full_like(straight, -radius)], axis=1)
    left = np.stack([-length / 2 - radius * np.sin(turn), -radius * np.cos(turn)], axis=1)
    points = np.concatenate([top, right, bottom, left])
    return np.roll(points, -len(straight) // 2, axis=0)


def stadium_length(length: float = 30.0, radius: float = 8.0) -> float:
    return 2 * length + 2 * np.pi * radius


def write_csv(path: Path, points: np.ndarray, header: str = "x_m,y_m") -> Path:
    lines = ([header] if header else []) + [f"{x:.4f},{y:.4f}" for x, y in points]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)
