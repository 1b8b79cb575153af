"""Pictures of a closed-loop run: the top-down trajectory over the circuit, and the camera's view.

`plot_trajectories` draws the road to scale with its red line underneath and every run's path on top,
coloured by the car's speed (one colour scale for all runs), a dot where each run started and a
mark where it ended (a cross when it left the road or got trapped, a square at a timeout, a
triangle after a completed lap). `CameraRecorder` keeps what the brain saw: an MP4 video (OpenCV,
at the control rate, each image held for as long as the brain took to decide) with the time and
command written on it, and a few JPEG stills spread over the run.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection, PolyCollection  # noqa: E402

from pilotlab.circuits.circuit import Circuit  # noqa: E402
from pilotlab.circuits.draw import colour, save_figure  # noqa: E402
from pilotlab.errors import PilotlabError  # noqa: E402
from pilotlab.online.trajectory import Trajectory  # noqa: E402
from pilotlab.sim.camera import GROUND, LINE, ROAD  # noqa: E402

END_MARKERS = {"lap_completed": "^", "timeout": "s", "off_road": "X", "trapped": "X"}


def _draw_road(axes, circuit: Circuit) -> None:
    left, right = circuit.offset_line(circuit.road_width / 2), circuit.offset_line(-circuit.road_width / 2)
    quads = np.stack([left, np.roll(left, -1, axis=0), np.roll(right, -1, axis=0), right], axis=1)
    axes.add_collection(PolyCollection(quads, facecolors=colour(ROAD), edgecolors=colour(ROAD), linewidths=0.3))
    loop = np.vstack([circuit.points, circuit.points[:1]])
    axes.plot(loop[:, 0], loop[:, 1], color=colour(LINE), linewidth=2.2, label="red line")


def _draw_run(axes, trajectory: Trajectory, norm) -> LineCollection:
    xy = np.stack([trajectory.x, trajectory.y], axis=1)
    segments = np.stack([xy[:-1], xy[1:]], axis=1)
    line = LineCollection(segments, cmap="plasma", norm=norm, linewidths=1.1)
    line.set_array((trajectory.speed[:-1] + trajectory.speed[1:]) / 2)
    axes.add_collection(line)
    axes.plot(xy[0, 0], xy[0, 1], "o", color="white", markeredgecolor="black", markersize=6)
    marker = END_MARKERS.get(trajectory.termination or "", "s")
    axes.plot(xy[-1, 0], xy[-1, 1], marker, color="white", markeredgecolor="black", markersize=8)
    return line


def plot_trajectories(circuit: Circuit, trajectories: Sequence[Trajectory], path: Path, *, title: str = "",
                      dpi: int = 110) -> Path:
    """Save the picture (format from the suffix, e.g. trajectory.png)."""
    if not trajectories:
        raise PilotlabError("plot_trajectories: no runs to draw")
    x0, y0, x1, y1 = circuit.bounds(margin=circuit.road_width + 4)
    scale = 9.0 / max(x1 - x0, y1 - y0)
    figure, axes = plt.subplots(figsize=(max((x1 - x0) * scale, 4.0) + 1.6, max((y1 - y0) * scale, 3.0) + 0.8))
    axes.set_facecolor(colour(GROUND))
    _draw_road(axes, circuit)
    top = max(float(np.max(t.speed)) for t in trajectories)
    norm = plt.Normalize(0.0, max(top, 1.0))
    for trajectory in trajectories:
        line = _draw_run(axes, trajectory, norm)
    figure.colorbar(line, ax=axes, label="speed (m/s)", shrink=0.8)
    axes.set_xlim(x0, x1)
    axes.set_ylim(y0, y1)
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title or f"{circuit.name} ({circuit.direction})", fontsize=9)
    return save_figure(figure, path, dpi)


class CameraRecorder:
    """Receives each camera image with the command decided on it (`drive`'s on_frame) and writes a
    video of the first `video_seconds` simulated seconds and/or `stills` JPEG stills."""

    def __init__(self, out: Path, *, control_hz: float, video_seconds: float | None = None, stills: int = 0,
                 still_every_s: float = 1.0):
        self.out, self.fps, self.video_seconds = Path(out), float(control_hz), video_seconds
        self.stills, self.still_every_s = stills, still_every_s
        self._writer, self._written, self._candidates = None, 0, []

    def wants(self, t: float) -> bool:
        """Whether an image seen at simulated time `t` would be kept (so a caller renders only those)."""
        return bool((self.video_seconds and t <= self.video_seconds)
                    or (self.stills and t >= len(self._candidates) * self.still_every_s))

    def __call__(self, image: np.ndarray | None, info: dict[str, Any], command) -> None:
        if image is None:
            return
        t = info["sim_time"]
        if self.video_seconds and t <= self.video_seconds:
            self._video_frame(image, t, command)
        if self.stills and t >= len(self._candidates) * self.still_every_s:
            ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(image, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])
            self._candidates.append((t, jpeg))

    def _video_frame(self, image: np.ndarray, t: float, command) -> None:
        bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
        if self._writer is None:
            self.out.mkdir(parents=True, exist_ok=True)
            height, width = bgr.shape[:2]
            self._writer = cv2.VideoWriter(str(self.out / "camera.mp4"), cv2.VideoWriter_fourcc(*"mp4v"),
                                           self.fps, (width, height))
            if not self._writer.isOpened():
                raise PilotlabError(f"OpenCV cannot write {self.out / 'camera.mp4'} (no mp4v encoder?); "
                                    "run without the video option")
        text = f"t {t:5.2f} s  v {command[0]:5.2f} m/s  w {command[1]:+5.2f} rad/s"
        cv2.putText(bgr, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
        # Hold the image until the next one: the video runs in simulated time at the control rate.
        for _ in range(max(1, int(t * self.fps) + 1 - self._written)):
            self._writer.write(bgr)
            self._written += 1

    def close(self) -> dict[str, Any]:
        """Finish the files; returns {"video": name} and/or {"camera_frames": [names]} (relative to out)."""
        written: dict[str, Any] = {}
        if self._writer is not None:
            self._writer.release()
            written["video"] = "camera.mp4"
        if self.stills and self._candidates:
            picks = np.unique(np.linspace(0, len(self._candidates) - 1, self.stills).round().astype(int))
            (self.out / "frames").mkdir(parents=True, exist_ok=True)
            names = []
            for i in picks:
                t, jpeg = self._candidates[i]
                name = f"frames/camera_{t:06.2f}s.jpg"
                (self.out / name).write_bytes(jpeg.tobytes())
                names.append(name)
            written["camera_frames"] = names
        return written
