"""The network's view: the camera rendering only the pixels a network's preprocessing keeps.

A recorded frame is the full 640×480 image; `pilotlab.data.preprocess` crops its rows, then ("fast_area")
averages 2×2 blocks while the crop is at least twice the network's size (640×240 -> 320×120 for
DeepLearningStudio's 200×66), then resizes bilinearly to the network's size. In the closed loop, rendering
the full frame to throw three quarters of it away costs most of the loop, so the ground renderer draws
only one sample per averaged block, at the block's centre (a PixelGrid), and the same last step
(`preprocess.finish`) makes the network's frame.

The one difference from record-then-preprocess: each block is sampled once at its centre instead of
averaged over its 2×2 (or 4×4...) pixels, so where an edge (line, road) crosses a block the colour is
one side's instead of the mix; the final bilinear resize smooths it further. Elsewhere the pixels are
equal. tests/pilotlab/sim/test_view.py measures the difference on poses around a circuit.
With "area" or "linear" interpolation there is no block structure to sample: the crop is rendered at
full resolution (the same pixels as the recorded frame's rows) and resized as preprocessing does, and
the pybullet renderer renders the full frame and preprocesses it.

    env = DrivingEnv("simple_circuit", camera=CameraSpec(), renderer="ground", view=PreprocessConfig())
    frame, info = env.reset()          # frame: uint8 66×200×3, what `preprocess` makes of the frame
"""
from __future__ import annotations

import numpy as np

from pilotlab.circuits.circuit import Circuit
from pilotlab.data.preprocess import PreprocessConfig, finish, preprocess
from pilotlab.sim.camera import CameraSpec, PixelGrid
from pilotlab.sim.render import GroundRenderer


def network_grid(camera: CameraSpec, config: PreprocessConfig) -> PixelGrid:
    """The samples of the full frame that stand for what preprocessing keeps before its last resize:
    one per block that "fast_area" averages (the halvings of `preprocess.resize`), at the block's
    centre; the kept rows at full resolution for the other interpolations."""
    rows = config.rows(camera.height)
    width, height, scale = camera.width, rows.stop - rows.start, 1
    if config.interpolation == "fast_area":
        while width >= 2 * config.width and height >= 2 * config.height:  # as `resize` halves (odd ends dropped)
            width, height, scale = width // 2, height // 2, scale * 2
    centre = (scale - 1) / 2
    return PixelGrid(width, height, float(scale), centre, rows.start + centre)


class GroundView:
    """The ground renderer drawing the network's view (see the module docstring)."""

    def __init__(self, circuit: Circuit, camera: CameraSpec, config: PreprocessConfig):
        self.config = config
        self.renderer = GroundRenderer(circuit, camera, grid=network_grid(camera, config))

    def render(self, eye: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        return finish(self.renderer.render(eye, rotation), self.config)


class WorldView:
    """The BM world renderer drawing the network's view (pilotlab.worlds.render), as GroundView does."""

    def __init__(self, world, camera: CameraSpec, config: PreprocessConfig):
        from pilotlab.worlds.render import WorldRenderer
        self.config = config
        self.renderer = WorldRenderer(world, camera, grid=network_grid(camera, config))

    def render(self, eye: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        return finish(self.renderer.render(eye, rotation), self.config)


def bm_renderer(world, name: str, client: int, camera: CameraSpec, config: PreprocessConfig | None):
    """The renderer of a BM world: "ground" the fast one (its network view with `config`), "pybullet"
    TinyRenderer over the world's meshes (preprocessed with `config`)."""
    from pilotlab.worlds.render import BulletWorldRenderer, WorldRenderer
    if name == "ground":
        return WorldView(world, camera, config) if config is not None else WorldRenderer(world, camera)
    renderer = BulletWorldRenderer(client, camera)
    return renderer if config is None else PreprocessedView(renderer, config)


class PreprocessedView:
    """Any renderer's full frame, preprocessed: the reference the ground view is compared with."""

    def __init__(self, renderer, config: PreprocessConfig):
        self.renderer, self.config = renderer, config

    def render(self, eye: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        return preprocess(self.renderer.render(eye, rotation), self.config)
