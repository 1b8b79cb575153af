"""A BM world in pybullet: its collision meshes as static, solid bodies (the car hits the walls), and
its visual meshes for TinyRenderer (the reference renderer, pilotlab.worlds.render.BulletWorldRenderer).

Visual meshes are the ground layers (lifted 0.1 mm per layer in painting order, so that coplanar faces
do not fight) and the solids, lit as the fast renderer lights them; textures go through PNG files
(pybullet loads textures from files only).
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import cv2
import numpy as np

from pilotlab.sim.bullet import p
from pilotlab.worlds.raster import filtered_texture
from pilotlab.worlds.scene import Layer
from pilotlab.worlds.world import BMWorld

TRIANGLES_PER_SHAPE = 1000      # pybullet bounds the vertices of one mesh shape
LAYER_LIFT_M = 0.0001


def _chunks(triangles: np.ndarray):
    for start in range(0, len(triangles), TRIANGLES_PER_SHAPE):
        chunk = triangles[start:start + TRIANGLES_PER_SHAPE]
        yield chunk.reshape(-1, 3), np.arange(len(chunk) * 3)


def add_collisions(client: int, world: BMWorld) -> list[int]:
    """The world's collision meshes as static concave bodies; returns their body ids."""
    bodies = []
    for vertices, indices in _chunks(world.collision_triangles):
        shape = p.createCollisionShape(p.GEOM_MESH, vertices=vertices.tolist(), indices=indices.tolist(),
                                       flags=p.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=client)
        bodies.append(p.createMultiBody(0, shape, -1, [0, 0, 0], physicsClientId=client))
    return bodies


def add_visuals(client: int, world: BMWorld) -> None:
    """The ground layers and the solids as visual-only meshes (for TinyRenderer)."""
    layers = world.ground_layers()
    with tempfile.TemporaryDirectory(prefix="pilotlab-textures-") as folder:
        for order, layer in enumerate(layers):
            _add_layer(client, layer, world.meta["ground_shade"], order * LAYER_LIFT_M, Path(folder) / f"{order}.png")
    for colour in np.unique(world.solid_colours, axis=0):
        chosen = world.solid_triangles[np.all(world.solid_colours == colour, axis=1)]
        _add_mesh(client, chosen, _rgba(colour))


def _rgba(rgb) -> list[float]:
    return [float(c) / 255 for c in rgb] + [1.0]


def _add_mesh(client: int, triangles: np.ndarray, rgba, uv_map=None, texture: int | None = None) -> None:
    for vertices, indices in _chunks(triangles):
        options = {}
        if uv_map is not None:
            uv = np.column_stack([vertices[:, :2], np.ones(len(vertices))]) @ uv_map.T
            options["uvs"] = uv.tolist()
        shape = p.createVisualShape(p.GEOM_MESH, vertices=vertices.tolist(), indices=indices.tolist(),
                                    rgbaColor=rgba, physicsClientId=client, **options)
        body = p.createMultiBody(0, -1, shape, [0, 0, 0], physicsClientId=client)
        if texture is not None:
            p.changeVisualShape(body, -1, textureUniqueId=texture, rgbaColor=[1, 1, 1, 1], physicsClientId=client)


def _add_layer(client: int, layer: Layer, shade: float, lift: float, png: Path) -> None:
    triangles = np.concatenate([layer.triangles, np.full(layer.triangles.shape[:2] + (1,), layer.height + lift)],
                               axis=2)
    if layer.texture is None or layer.uv_map is None:
        _add_mesh(client, triangles, _rgba(np.array(layer.colour) * shade))
        return
    image = np.clip(filtered_texture(layer, 0.01) * (np.array(layer.colour) / 255 * shade), 0, 255).astype(np.uint8)
    cv2.imwrite(str(png), image[:, :, ::-1])
    texture = p.loadTexture(str(png), physicsClientId=client)
    _add_mesh(client, triangles, [1, 1, 1, 1], layer.uv_map, texture)
