"""BehaviorMetrics' SDF files, read with ElementTree: what a world holds and where.

A `.world` includes models by `model://NAME` URIs with a pose; a model's `model.sdf` (or the file its
`model.config` names) holds links with poses, visual and collision meshes (COLLADA) and, for the car,
the camera sensor. Poses are SDF's `x y z roll pitch yaw` (fixed-axis roll, pitch, then yaw).
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pilotlab.errors import PilotlabError

# The camera whose images BM's follow-line brains read: the plugin publishes /F1ROS/cameraL/image_raw.
CAR_CAMERA_NAME = "F1ROS/cameraL"


@dataclass(frozen=True)
class Mesh:
    """A COLLADA file placed in the world: `transform` (4×4) maps the file's metres to world metres."""
    path: Path
    transform: np.ndarray = field(compare=False)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class Camera:
    """A camera sensor: its pose in the car's frame and its optics."""
    pose: tuple[float, ...]           # x y z roll pitch yaw, metres and radians, in the car frame
    hfov_rad: float
    width: int
    height: int
    near_m: float
    far_m: float


@dataclass(frozen=True)
class WorldFile:
    """What pilotlab needs from a .world: meshes (visual and collision), the car's spawn pose and camera,
    the lighting and the sky."""
    name: str
    visuals: tuple[Mesh, ...]
    collisions: tuple[Mesh, ...]
    spawn: tuple[float, ...] | None   # x y z roll pitch yaw of the car
    camera: Camera | None
    sun: tuple[float, ...] | None     # direction (x, y, z) and diffuse (r, g, b) of the directional light
    ambient: tuple[float, float, float]
    sky: bool
    files: tuple[Path, ...]           # every file read (the cache key)
    path: Path | None = None          # the .world file


def parse_xml(path: Path) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as error:
        raise PilotlabError(f"{path}: not valid XML ({error}); the file is damaged") from None
    except OSError as error:
        raise PilotlabError(f"{path}: cannot be read ({error.strerror})") from None


def numbers(text: str | None, count: int, where: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in (text or "").split())
    except ValueError:
        values = ()
    if len(values) != count:
        raise PilotlabError(f"{where}: expected {count} numbers, got {text!r}")
    return values


def pose_matrix(pose) -> np.ndarray:
    """4×4 of an SDF pose (x y z roll pitch yaw): R = Rz(yaw) Ry(pitch) Rx(roll)."""
    x, y, z, roll, pitch, yaw = pose
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    matrix = np.eye(4)
    matrix[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                      [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                      [-sp, cp * sr, cp * cr]]
    matrix[:3, 3] = (x, y, z)
    return matrix


def _pose(element: ET.Element, where: str) -> tuple[float, ...]:
    found = element.find("pose")
    return (0.0,) * 6 if found is None else numbers(found.text, 6, f"{where} <pose>")


def read_world(path: Path, assets: Path) -> WorldFile:
    root = parse_xml(path)
    world = root.find("world")
    if world is None:
        raise PilotlabError(f"{path}: no <world> element; is it an SDF world file?")
    reader = _Reader(assets, [path])
    for include in world.findall("include"):
        reader.include(include, path)
    for light in world.findall("light"):
        reader.light(light, path)
    scene = world.find("scene")
    ambient = (1.0, 1.0, 1.0)
    if scene is not None and scene.find("ambient") is not None:
        ambient = numbers(scene.find("ambient").text, 4, f"{path} <scene><ambient>")[:3]
    sky = scene is not None and scene.find("sky") is not None
    return WorldFile(path.stem, tuple(reader.visuals), tuple(reader.collisions), reader.spawn, reader.camera,
                     reader.sun, ambient, sky, tuple(reader.files), path)


class _Reader:
    """Walks the includes of a world, collecting meshes, the car and the light."""

    def __init__(self, assets: Path, files: list[Path]):
        self.assets, self.files = assets, files
        self.visuals: list[Mesh] = []
        self.collisions: list[Mesh] = []
        self.spawn = self.camera = self.sun = None

    def include(self, include: ET.Element, where: Path) -> None:
        uri = (include.findtext("uri") or "").strip()
        if not uri.startswith("model://"):
            raise PilotlabError(f"{where}: include of {uri!r}: only model:// URIs are understood")
        name = uri[len("model://"):].strip("/")
        pose = _pose(include, f"{where} include {uri}")
        model_file = self.model_file(name, where)
        model = parse_xml(model_file)
        self.files.append(model_file)
        if model.tag == "gazebo" or model.find("light") is not None:  # the sun: a light, not a model
            for light in model.iter("light"):
                self.light(light, model_file)
            return
        self.model(model.find("model"), pose_matrix(pose), model_file, pose)

    def model_file(self, name: str, where: Path) -> Path:
        folder = self.assets / "models" / name
        if not folder.is_dir():
            raise PilotlabError(f"{where}: includes model://{name}, but {folder} does not exist")
        config = folder / "model.config"
        if config.is_file():
            self.files.append(config)
            for sdf in parse_xml(config).findall("sdf"):
                candidate = folder / (sdf.text or "").strip()
                if candidate.is_file():
                    return candidate
        if (folder / "model.sdf").is_file():
            return folder / "model.sdf"
        raise PilotlabError(f"{folder}: has neither model.sdf nor a model.config naming its SDF file")

    def model(self, model: ET.Element | None, placed: np.ndarray, where: Path, pose) -> None:
        if model is None:
            raise PilotlabError(f"{where}: no <model> element")
        camera = _car_camera(model, where)
        if camera is not None:
            self.spawn, self.camera = tuple(pose), camera
            return  # the car: only its camera and pose matter (its body meshes are not drawn)
        for link in model.findall("link"):
            at = placed @ pose_matrix(_pose(link, f"{where} link {link.get('name')}"))
            for kind, found in (("visual", self.visuals), ("collision", self.collisions)):
                for element in link.findall(kind):
                    mesh = self.mesh(element, at, where)
                    if mesh is not None:
                        found.append(mesh)

    def mesh(self, element: ET.Element, link: np.ndarray, where: Path) -> Mesh | None:
        geometry = element.find("geometry/mesh")
        if geometry is None:
            return None  # planes, boxes: the ground plane needs no mesh
        uri = (geometry.findtext("uri") or "").strip()
        if not uri.startswith("model://"):
            raise PilotlabError(f"{where}: mesh {uri!r}: only model:// URIs are understood")
        path = self.assets / "models" / uri[len("model://"):]
        if not path.is_file():
            raise PilotlabError(f"{where}: mesh {uri} is missing ({path} does not exist)")
        self.files.append(path)
        scale = geometry.findtext("scale")
        scale = numbers(scale, 3, f"{where} mesh {uri} <scale>") if scale else (1.0, 1.0, 1.0)
        transform = link @ pose_matrix(_pose(element, f"{where} {uri}")) @ np.diag([*scale, 1.0])
        return Mesh(path, transform, scale)

    def light(self, light: ET.Element, where: Path) -> None:
        if light.get("type") != "directional":
            return
        direction = numbers(light.findtext("direction"), 3, f"{where} <light><direction>")
        diffuse = numbers(light.findtext("diffuse"), 4, f"{where} <light><diffuse>")[:3]
        self.sun = (*direction, *diffuse)


def _car_camera(model: ET.Element, where: Path) -> Camera | None:
    """The camera BM's brains read: the sensor whose plugin publishes F1ROS/cameraL, else the first one."""
    sensors = [s for s in model.iter("sensor") if s.get("type") in ("camera", "wideanglecamera")]
    if not sensors:
        return None
    named = [s for s in sensors if any((e.text or "").strip() == CAR_CAMERA_NAME for e in s.iter("cameraName"))]
    sensor = (named or sensors)[0]
    label = f"{where} sensor {sensor.get('name')}"
    optics = sensor.find("camera")
    if optics is None:
        raise PilotlabError(f"{label}: no <camera> element")
    size = optics.find("image")
    return Camera(pose=_pose(sensor, label),
                  hfov_rad=numbers(optics.findtext("horizontal_fov"), 1, f"{label} <horizontal_fov>")[0],
                  width=int(numbers(size.findtext("width") if size is not None else None, 1, f"{label} width")[0]),
                  height=int(numbers(size.findtext("height") if size is not None else None, 1, f"{label} height")[0]),
                  near_m=numbers(optics.findtext("clip/near"), 1, f"{label} <clip><near>")[0],
                  far_m=numbers(optics.findtext("clip/far"), 1, f"{label} <clip><far>")[0])
