"""A small BehaviorMetrics-like world written by the tests themselves (SDF + COLLADA), so that a fresh
clone tests the importer without BM's files: a stadium circuit (road with a texture, a red line, grass)
in a mesh whose unit is the inch, under a node transform, inside a model placed with a pose; walls in
metres; the car with BM's camera; a sun; the centreline as worlds/oval.csv."""
from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from tests.pilotlab.tracks import stadium, write_csv

INCH = 0.0254
MODEL_POSE = (2.0, 1.0, 0.0, 0.0, 0.0, 0.2)      # x y z roll pitch yaw of the circuit model
NODE_OFFSET_M = (1.5, -0.5)                     # the mesh node's translation
ROAD_M, LINE_M, GRASS_M, WALL_M = 4.0, 0.1, 8.0, 5.0   # widths; walls stand WALL_M from the line


def centreline() -> np.ndarray:
    return stadium(length=20.0, radius=8.0, spacing=0.1)


def _normals(points: np.ndarray) -> np.ndarray:
    tangent = np.roll(points, -1, axis=0) - np.roll(points, 1, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)


def band(points: np.ndarray, left: float, right: float, z: float) -> np.ndarray:
    """Triangles (n, 3, 3) of the band between offsets `left` and `right` of a closed polyline, facing up."""
    normal = _normals(points)
    a, b = points + left * normal, points + right * normal
    a2, b2 = np.roll(a, -1, axis=0), np.roll(b, -1, axis=0)
    quads = [(b, b2, a2), (b, a2, a)]    # counter-clockwise seen from above for a clockwise... checked below
    triangles = np.concatenate([np.stack(quad, axis=1) for quad in quads])
    triangles = np.concatenate([triangles, np.full(triangles.shape[:2] + (1,), z)], axis=2)
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])[:, 2]
    triangles[cross < 0] = triangles[cross < 0][:, ::-1]
    return triangles


def wall(points: np.ndarray, offset: float, height: float = 0.5) -> np.ndarray:
    """Vertical triangles (both faces) of a wall along the offset line."""
    line = points[::5] + offset * _normals(points)[::5]
    a, b = line, np.roll(line, -1, axis=0)
    low_a, low_b = np.c_[a, np.zeros(len(a))], np.c_[b, np.zeros(len(b))]
    high_a, high_b = low_a + [0, 0, height], low_b + [0, 0, height]
    front = np.concatenate([np.stack([low_a, low_b, high_b], 1), np.stack([low_a, high_b, high_a], 1)])
    return np.concatenate([front, front[:, ::-1]])


def to_model(points_xyz: np.ndarray) -> np.ndarray:
    """World -> the circuit model's frame (the inverse of MODEL_POSE; yaw only)."""
    x, y, _, _, _, yaw = MODEL_POSE
    c, s = math.cos(yaw), math.sin(yaw)
    shifted = points_xyz - [x, y, 0.0]
    return np.stack([c * shifted[..., 0] + s * shifted[..., 1], -s * shifted[..., 0] + c * shifted[..., 1],
                     shifted[..., 2]], axis=-1)


def _floats(values) -> str:
    return " ".join(f"{v:.6f}" for v in np.ravel(values))


def collada(parts: list[tuple[np.ndarray, str, str | None]], unit: float, node_offset=(0.0, 0.0),
            unit_name: str = "inch") -> str:
    """A COLLADA 1.4 document: each part is (triangles in file units, RGB hex colour, texture file or None)."""
    images, materials, effects, geometries, instances = [], [], [], [], []
    for i, (triangles, colour, texture) in enumerate(parts):
        rgb = " ".join(f"{int(colour[k:k + 2], 16) / 255:.4f}" for k in (0, 2, 4))
        if texture:
            images.append(f'<image id="img{i}"><init_from>{texture}</init_from></image>')
            diffuse = (f'<newparam sid="surf{i}"><surface type="2D"><init_from>img{i}</init_from></surface></newparam>'
                       f'<newparam sid="samp{i}"><sampler2D><source>surf{i}</source></sampler2D></newparam>'
                       f'<technique sid="COMMON"><lambert><diffuse><texture texture="samp{i}" texcoord="UVSET0"/>'
                       f'</diffuse></lambert></technique>')
        else:
            diffuse = f'<technique sid="COMMON"><lambert><diffuse><color>{rgb} 1</color></diffuse></lambert></technique>'
        effects.append(f'<effect id="fx{i}"><profile_COMMON>{diffuse}</profile_COMMON></effect>')
        materials.append(f'<material id="mat{i}"><instance_effect url="#fx{i}"/></material>')
        vertices = triangles.reshape(-1, 3)
        uv = vertices[:, :2] * unit / 1.0            # one texture repeat per metre, planar
        count = len(triangles)
        indices = np.repeat(np.arange(count * 3), 2)
        geometries.append(
            f'<geometry id="geo{i}"><mesh>'
            f'<source id="pos{i}"><float_array id="pa{i}" count="{vertices.size}">{_floats(vertices)}</float_array>'
            f'<technique_common><accessor source="#pa{i}" count="{len(vertices)}" stride="3"><param name="X" type="float"/>'
            f'<param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>'
            f'<source id="uv{i}"><float_array id="ua{i}" count="{uv.size}">{_floats(uv)}</float_array>'
            f'<technique_common><accessor source="#ua{i}" count="{len(uv)}" stride="2"><param name="S" type="float"/>'
            f'<param name="T" type="float"/></accessor></technique_common></source>'
            f'<vertices id="v{i}"><input semantic="POSITION" source="#pos{i}"/></vertices>'
            f'<triangles material="m{i}" count="{count}"><input semantic="VERTEX" source="#v{i}" offset="0"/>'
            f'<input semantic="TEXCOORD" source="#uv{i}" offset="1" set="0"/><p>{" ".join(map(str, indices))}</p>'
            f'</triangles></mesh></geometry>')
        instances.append(f'<instance_geometry url="#geo{i}"><bind_material><technique_common>'
                         f'<instance_material symbol="m{i}" target="#mat{i}">'
                         f'<bind_vertex_input semantic="UVSET0" input_semantic="TEXCOORD" input_set="0"/>'
                         f'</instance_material></technique_common></bind_material></instance_geometry>')
    tx, ty = node_offset
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">'
            f'<asset><unit meter="{unit}" name="{unit_name}"/><up_axis>Z_UP</up_axis></asset>'
            f'<library_images>{"".join(images)}</library_images><library_materials>{"".join(materials)}</library_materials>'
            f'<library_effects>{"".join(effects)}</library_effects><library_geometries>{"".join(geometries)}'
            f'</library_geometries><library_visual_scenes><visual_scene id="scene"><node name="track">'
            f'<matrix>1 0 0 {tx} 0 1 0 {ty} 0 0 1 0 0 0 0 1</matrix>{"".join(instances)}</node></visual_scene>'
            f'</library_visual_scenes><scene><instance_visual_scene url="#scene"/></scene></COLLADA>\n')


CAR_SDF = """<?xml version="1.0"?>
<sdf version="1.5"><model name="f1"><link name="chassis"><sensor name="cam_f1_left" type="camera">
<pose>0.45 0.04 0.1 0 0 0</pose><camera name="cleft"><horizontal_fov>1.57</horizontal_fov>
<image><width>640</width><height>480</height><format>R8G8B8</format></image><clip><near>0.1</near><far>15</far></clip>
</camera><plugin name="cam" filename="libgazebo_ros_camera.so"><cameraName>F1ROS/cameraL</cameraName></plugin>
</sensor></link></model></sdf>
"""
SUN_SDF = """<?xml version="1.0"?>
<gazebo version="1.2"><light type="directional" name="sun"><diffuse>0.8 0.8 0.8 1</diffuse>
<direction>-0.5 0.5 -1.0</direction></light></gazebo>
"""


def world_sdf(sun: bool = True) -> str:
    sun_include = "<include><uri>model://sun</uri></include>" if sun else ""
    x, y, yaw = centreline()[0][0], centreline()[0][1], 0.0
    return (f'<?xml version="1.0"?>\n<sdf version="1.5"><world name="default">{sun_include}'
            f'<include><uri>model://oval</uri><pose>{_floats(MODEL_POSE)}</pose></include>'
            f'<include><uri>model://f1</uri><pose>{x:.3f} {y:.3f} 0.004 0 0 {yaw}</pose></include>'
            f'<scene><sky><clouds><speed>12</speed></clouds></sky><ambient>1 1 1 1</ambient></scene>'
            f'</world></sdf>\n')


MODEL_SDF = """<?xml version="1.0"?>
<sdf version="1.5"><model name="oval"><static>true</static>
<link name="track"><visual name="visual"><geometry><mesh><uri>model://oval/meshes/track.dae</uri></mesh></geometry></visual></link>
<link name="walls"><collision name="collision"><geometry><mesh><uri>model://oval/meshes/walls.dae</uri></mesh></geometry></collision>
<visual name="visual"><geometry><mesh><uri>model://oval/meshes/walls.dae</uri></mesh></geometry></visual></link>
</model></sdf>
"""


def write_world(root: Path, sun: bool = True, grass_beside: float | None = None) -> Path:
    """Write the assets folder (worlds/oval.world + worlds/oval_no_sun.world, models/...) under `root`; with
    `grass_beside`, the grass is two strips that wide beside the road (less area than the road's, as in BM's
    many_curves), not a band under it."""
    points = centreline()
    meshes = root / "models" / "oval" / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    (root / "worlds").mkdir(exist_ok=True)
    for name in ("f1", "sun"):
        (root / "models" / name).mkdir(exist_ok=True)
    (root / "models" / "f1" / "model.sdf").write_text(CAR_SDF)
    (root / "models" / "sun" / "model.sdf").write_text(SUN_SDF)
    (root / "models" / "oval" / "model.sdf").write_text(MODEL_SDF)
    texture = np.random.default_rng(0).integers(60, 100, (64, 64, 3)).astype(np.uint8)
    cv2.imwrite(str(meshes / "asphalt.png"), texture)
    offset = np.array([*NODE_OFFSET_M, 0.0])
    grass = [(band(points, GRASS_M, -GRASS_M, 0.0), "4f7a3a", None)] if grass_beside is None else \
        [(band(points, sign * (ROAD_M / 2 + grass_beside), sign * ROAD_M / 2, 0.0), "4f7a3a", None) for sign in (1, -1)]
    track = [*grass,
             (band(points, ROAD_M / 2, -ROAD_M / 2, 0.0), "ffffff", "asphalt.png"),
             (band(points, LINE_M / 2, -LINE_M / 2, 0.002), "ff0000", None)]
    inches = [((to_model(t) - offset) / INCH, colour, tex) for t, colour, tex in track]
    (meshes / "track.dae").write_text(collada(inches, INCH, np.array(NODE_OFFSET_M) / INCH))
    walls = np.concatenate([wall(points, WALL_M), wall(points, -WALL_M)])
    (meshes / "walls.dae").write_text(collada([(to_model(walls), "a3a3a3", None)], 1.0, unit_name="meter"))
    (root / "worlds" / "oval.world").write_text(world_sdf(sun=True))
    (root / "worlds" / "oval_no_sun.world").write_text(world_sdf(sun=False))
    write_csv(root / "worlds" / "oval.csv", points)
    write_csv(root / "worlds" / "oval_no_sun.csv", points)
    return root
