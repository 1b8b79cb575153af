"""A map of a circuit: the road to scale on grass, the red line, the start and the driving direction."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

from pilotlab.circuits.circuit import Circuit  # noqa: E402
from pilotlab.sim.camera import GROUND, LINE, ROAD  # noqa: E402


def colour(rgb) -> tuple[float, float, float]:
    """A 0-255 RGB triple as matplotlib's 0-1 one."""
    return tuple(c / 255 for c in rgb)


def save_figure(figure, path: Path, dpi: int) -> Path:
    """Write a pyplot figure to `path` (folders made as needed) and free it."""
    figure.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    return path


def draw_map(circuit: Circuit, path: Path, *, paths: dict[str, np.ndarray] | None = None, dpi: int = 100) -> Path:
    """Save the map as an image (format from the suffix); `paths` adds driven trajectories (x, y arrays)."""
    x0, y0, x1, y1 = circuit.bounds(margin=circuit.road_width + 4)
    scale = 10.0 / max(x1 - x0, y1 - y0)
    figure, axes = plt.subplots(figsize=(max((x1 - x0) * scale, 4.0), max((y1 - y0) * scale, 3.0) + 0.6))
    axes.set_facecolor(colour(GROUND))
    left, right = circuit.offset_line(circuit.road_width / 2), circuit.offset_line(-circuit.road_width / 2)
    quads = np.stack([left, np.roll(left, -1, axis=0), np.roll(right, -1, axis=0), right], axis=1)
    axes.add_collection(PolyCollection(quads, facecolors=colour(ROAD), edgecolors=colour(ROAD), linewidths=0.3))
    loop = np.vstack([circuit.points, circuit.points[:1]])
    axes.plot(loop[:, 0], loop[:, 1], color=colour(LINE), linewidth=1.0, label="red line")
    for label, xy in (paths or {}).items():
        axes.plot(xy[:, 0], xy[:, 1], linewidth=0.8, label=label)
    _start_arrow(axes, circuit)
    axes.set_xlim(x0, x1)
    axes.set_ylim(y0, y1)
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(f"{circuit.name} ({circuit.direction}): {circuit.length:.0f} m, road {circuit.road_width:g} m")
    if paths:
        axes.legend(loc="best", fontsize=8)
    return save_figure(figure, path, dpi)


def _start_arrow(axes, circuit: Circuit) -> None:
    x, y, heading = circuit.start_pose(0.0)
    length = max(8.0, circuit.length / 60)
    axes.annotate("start", xy=(x + length * np.cos(heading), y + length * np.sin(heading)), xytext=(x, y),
                  arrowprops={"arrowstyle": "-|>", "color": "white", "lw": 1.5}, color="white", fontsize=9,
                  ha="center", va="center")
