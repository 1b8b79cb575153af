"""A BehaviorMetrics world ready to drive in: read once from its SDF + COLLADA files, turned into
ground rasters, solids and collision triangles, and cached by the files' content.

    world = load_world("simple_circuit", assets="../shared/data/bm_worlds")
    world.circuit("cw"), world.camera(), world.spawn

The cache lives in $PILOTLAB_CACHE/worlds (default ~/.cache/pilotlab/worlds), one folder per
content digest: editing a mesh, a texture or an SDF file makes a new entry; nothing is ever read
stale. It holds numpy arrays and JSON only (no pickle).
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pilotlab.circuits.circuit import Circuit
from pilotlab.circuits.load import get_circuit
from pilotlab.circuits.registry import CIRCUITS
from pilotlab.errors import PilotlabError
from pilotlab.worlds.assets import content_digest, resolve_assets, world_path
from pilotlab.worlds.collada import read_mesh, texture_files
from pilotlab.worlds.raster import Grid, colour_raster, fill, signed_distance
from pilotlab.worlds.scene import Layer, split_scene
from pilotlab.worlds.sdf import WorldFile, read_world

CACHE_VERSION = 7
CACHE_ENV = "PILOTLAB_CACHE"
# Gazebo lights BM's lambert materials by the scene's ambient (1.0) times a share (they declare no
# ambient colour of their own) plus the sun's diffuse term; 0.4 is pilotlab's estimate of that share.
AMBIENT_SHARE = 0.4
VOID = (178, 178, 178)      # Gazebo's background, where no mesh is (beyond the grass)
LINE_RASTER_BYTES = 512 * 2**20
LINE_SEARCH_M = 0.3         # a layer within this of the centreline at >= 90 % of it is "the line"


@dataclass(frozen=True)
class Lighting:
    ambient: float
    sun: tuple[float, float, float] | None      # unit vector towards the sun, None without one
    diffuse: float

    @classmethod
    def of(cls, world: WorldFile) -> Lighting:
        ambient = AMBIENT_SHARE * float(np.mean(world.ambient))
        if world.sun is None:
            return cls(ambient, None, 0.0)
        direction = -np.asarray(world.sun[:3], float)
        return cls(ambient, tuple(direction / np.linalg.norm(direction)), float(np.mean(world.sun[3:])))

    def shade(self, normal) -> float:
        """Brightness (0-1) of a surface facing `normal` (both sides lit, as Gazebo's two-sided faces)."""
        lit = 0.0 if self.sun is None else abs(float(np.dot(normal, self.sun)))
        return min(1.0, self.ambient + self.diffuse * lit)


@dataclass
class BMWorld:
    """Everything the simulator needs of a BM world (see the module docstring)."""
    name: str
    digest: str
    grid: Grid
    colour: np.ndarray = field(repr=False)                  # lit ground colours (H, W, 3)
    labels: np.ndarray = field(repr=False)                  # top layer per raster pixel (0: none)
    sharp: list[dict] = field(repr=False)                   # flat-coloured layers drawn with sharp edges
    distances: list[np.ndarray] = field(repr=False)
    solid_triangles: np.ndarray = field(repr=False)         # (n, 3, 3) walls, posts
    solid_colours: np.ndarray = field(repr=False)           # (n, 3) lit RGB per triangle
    collision_triangles: np.ndarray = field(repr=False)     # (n, 3, 3) what the car can hit
    layers: list[dict] = field(repr=False)                  # colour, height, area, name per layer
    meta: dict = field(repr=False)

    @property
    def spawn(self) -> tuple[float, ...] | None:
        return tuple(self.meta["spawn"]) if self.meta["spawn"] else None

    @property
    def has_sun(self) -> bool:
        return self.meta["sun"]

    @property
    def road_width(self) -> float:
        return self.meta["road_width"]

    @property
    def line_colour(self) -> tuple[int, int, int] | None:
        index = self.meta["line_layer"]
        return None if index is None else tuple(self.layers[index]["colour"])

    def ground_layers(self) -> list[Layer]:
        """The ground layers with their triangles and textures (read again from the meshes: only the
        pybullet renderer needs them)."""
        _, parsed, digest = world_inputs(self.name, self.meta["assets"])
        if digest != self.digest:
            raise PilotlabError(f"world {self.name}: its files changed since it was loaded; load it again")
        return split_scene([part for mesh in parsed.visuals for part in read_mesh(mesh)])[0]

    def circuit(self, direction: str = "cw") -> Circuit:
        return get_circuit(self.meta["circuit"], direction, road_width=self.road_width)

    def camera(self, **options):
        """The world's own car camera (BM's F1 camera in its worlds), as a CameraSpec."""
        from pilotlab.sim.camera import CameraSpec
        camera = self.meta["camera"]
        settings = dict(width=camera["width"], height=camera["height"], hfov_deg=math.degrees(camera["hfov_rad"]),
                        aspect=camera["width"] / camera["height"], forward_m=camera["pose"][0],
                        lateral_m=camera["pose"][1], height_m=camera["pose"][2] + (self.spawn or (0, 0, 0))[2],
                        near_m=camera["near_m"], far_m=camera["far_m"], level=True)
        return CameraSpec(**{**settings, **options})


def circuit_of(name: str, world_file: Path | None = None) -> str:
    """The world's circuit: a centreline CSV beside the world file (worlds/NAME.csv, x,y per line in the
    world frame, as `pilotlab circuit` reads), else the built-in circuit (BM's perfect-lap centreline)
    whose name starts the world's name."""
    if world_file is not None and world_file.with_suffix(".csv").is_file():
        return str(world_file.with_suffix(".csv"))
    matches = [c for c in CIRCUITS.names() if name.startswith(c)]
    if not matches:
        raise PilotlabError(f"world {name!r}: no built-in circuit matches its name (known: "
                            f"{', '.join(CIRCUITS.names())}) and there is no {name}.csv centreline beside its "
                            ".world file; the centreline is needed for progress, laps and the BM metrics")
    return max(matches, key=len)


def cache_root() -> Path:
    base = os.environ.get(CACHE_ENV)
    return (Path(base) if base else Path.home() / ".cache" / "pilotlab") / "worlds"


def world_inputs(name: str, assets=None) -> tuple[Path, WorldFile, str]:
    """The world file, what it names, and the digest of every file it reads."""
    folder = resolve_assets(assets)
    path = world_path(folder, name)
    parsed = read_world(path, folder)
    centreline = path.with_suffix(".csv")
    textures = [image for mesh in parsed.visuals for image in texture_files(mesh.path)]
    files = [*parsed.files, *textures, *([centreline] if centreline.is_file() else [])]
    return path, parsed, content_digest(files)


def load_world(name: str, assets=None) -> BMWorld:
    _, parsed, digest = world_inputs(name, assets)
    entry = cache_root() / f"{name}-{digest[:16]}-v{CACHE_VERSION}"
    try:
        world = _read(entry)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):   # absent, or damaged from outside (a full disk,
        shutil.rmtree(entry, ignore_errors=True)                  # a partial copy; JSONDecodeError is a ValueError)
        _store(build_world(parsed, digest), entry)
        world = _read(entry)
    # where it was found this time (not part of the cached content)
    world.meta["assets"] = str(parsed.path.parent.parent)
    world.meta["circuit"] = circuit_of(parsed.name, parsed.path)
    return world


def build_world(parsed: WorldFile, digest: str) -> BMWorld:
    parts = [part for mesh in parsed.visuals for part in read_mesh(mesh)]
    layers, solids = split_scene(parts)
    if not layers:
        raise PilotlabError(f"world {parsed.name}: its meshes have no ground (no faces facing up at road level)")
    lighting = Lighting.of(parsed)
    ground_shade = lighting.shade((0.0, 0.0, 1.0))
    grid = Grid.around(layers)
    labels = label_raster(grid, layers)
    circuit_name = circuit_of(parsed.name, parsed.path)
    centreline = get_circuit(circuit_name).points
    line = find_line(grid, labels, centreline)
    # The line (what a brain follows, 10 cm wide) is drawn per frame with sharp edges from a fine
    # signed-distance raster; everything else comes from the colour raster (edges blurred over 5 cm).
    sharp = [] if line is None else [line]
    under = [layer for i, layer in enumerate(layers) if i not in sharp]
    colour = colour_raster(grid, under, [ground_shade] * len(under), VOID)
    solid_triangles, solid_colours = _solids(solids, lighting)
    collisions = [part.triangles for mesh in parsed.collisions for part in read_mesh(mesh)]
    line_grid = line_raster_grid(grid)
    sharp_grids = {i: line_grid if i == line else grid for i in sharp}
    meta = {"name": parsed.name, "digest": digest, "grid": grid.__dict__, "spawn": parsed.spawn,
            "ground_shade": ground_shade,
            "sun": parsed.sun is not None, "sky": parsed.sky, "circuit": circuit_name,
            "camera": None if parsed.camera is None else parsed.camera.__dict__, "line_layer": line,
            "road_width": measure_road_width(grid, labels, centreline, layers),
            "sharp": [{"index": i, "height": layers[i].height, "grid": sharp_grids[i].__dict__,
                       "colour": [int(round(c * ground_shade)) for c in layers[i].colour]} for i in sharp],
            "layers": [{"colour": list(l.colour), "height": l.height, "area": l.area, "name": l.name,
                        "textured": l.texture is not None} for l in layers]}
    if meta["camera"] is None:
        raise PilotlabError(f"world {parsed.name}: no car with a camera sensor is included; BM's worlds "
                            "include model://f1_renault")
    distances = [signed_distance(sharp_grids[i], layers[i]) for i in sharp]
    return BMWorld(parsed.name, digest, grid, colour, labels, meta["sharp"], distances, solid_triangles,
                   solid_colours, np.concatenate(collisions) if collisions else np.zeros((0, 3, 3)),
                   meta["layers"], meta)


def line_raster_grid(grid: Grid) -> Grid:
    """The line is thin (10 cm): its edges are drawn from a raster up to 4× finer than the ground's, as
    fine as LINE_RASTER_BYTES allows (the renderer memory-maps it: only what the camera sees is read)."""
    for factor in (4, 2):
        if grid.width * grid.height * factor**2 <= LINE_RASTER_BYTES:
            return grid.finer(factor)
    return grid


def label_raster(grid: Grid, layers: list[Layer]) -> np.ndarray:
    labels = np.zeros((grid.height, grid.width), np.uint8)
    for index, layer in enumerate(layers):
        fill(labels, grid, layer.triangles, index + 1)
    return labels


def _sample(grid: Grid, labels: np.ndarray, points: np.ndarray) -> np.ndarray:
    cols = np.clip(np.round((points[..., 0] - grid.x0) / grid.resolution).astype(int), 0, grid.width - 1)
    rows = np.clip(np.round((grid.y1 - points[..., 1]) / grid.resolution).astype(int), 0, grid.height - 1)
    return labels[rows, cols]


def find_line(grid: Grid, labels: np.ndarray, centreline: np.ndarray) -> int | None:
    """The layer found within LINE_SEARCH_M of (nearly) every centreline point: the line to follow."""
    offsets = np.linspace(-LINE_SEARCH_M, LINE_SEARCH_M, 13)
    normal = _normals(centreline)
    samples = _sample(grid, labels, centreline[:, None, :] + offsets[None, :, None] * normal[:, None, :])
    candidates = [int(l) - 1 for l in np.unique(samples) if l and np.mean((samples == l).any(axis=1)) >= 0.9]
    if not candidates:
        return None
    areas = np.bincount(labels.ravel(), minlength=256)
    return min(candidates, key=lambda i: areas[i + 1])


def _normals(points: np.ndarray) -> np.ndarray:
    tangent = np.roll(points, -1, axis=0) - np.roll(points, 1, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)


def measure_road_width(grid: Grid, labels: np.ndarray, centreline: np.ndarray, layers: list[Layer]) -> float:
    """Median width, across the centreline, of what is neither the void nor the surrounding ground: the
    largest layer besides the road's own (the grass), where it is one of the world's large layers
    (LARGE_SHARE; BM's white_road has none: its road lies in the void). The car's centre must stay within
    it. (Not merely the largest layer: many_curves' asphalt is larger than its grass, and its road
    measured 0.175 m, the red line alone.)"""
    normal, points = _normals(centreline)[::5], centreline[::5]
    road = beside_the_line(grid, labels, points, normal)
    others = [i + 1 for i in range(len(layers)) if i + 1 != road]
    grass = max(others, key=lambda label: layers[label - 1].area, default=None)
    large = grass is not None and layers[grass - 1].area >= LARGE_SHARE * layers[road - 1].area if road else False
    outside = {0, grass} if large else {0}
    steps = np.arange(0.0, 15.0, grid.resolution / 2)
    widths = []
    for sign in (1, -1):
        samples = _sample(grid, labels, points[:, None, :] + sign * steps[None, :, None] * normal[:, None, :])
        off = np.isin(samples, list(outside))
        widths.append(steps[np.where(off.any(axis=1), off.argmax(axis=1), len(steps) - 1)])
    return float(np.median(widths[0] + widths[1]))


# the grass: a layer of at least this share of the road's area (white_road's largest besides its road is a
# grey strip of 7 %: its road lies in the void)
LARGE_SHARE = 0.25
ROAD_SAMPLE_M = 1.0   # beside the red line (0.1-0.2 m wide), within the road's half width (1.6-1.7 m)


def beside_the_line(grid: Grid, labels: np.ndarray, points: np.ndarray, normal: np.ndarray) -> int | None:
    """The label most often found ROAD_SAMPLE_M either side of the centreline (the road's layer), or None."""
    near = np.concatenate([_sample(grid, labels, points + sign * ROAD_SAMPLE_M * normal) for sign in (1, -1)])
    near = near[near != 0]
    if not len(near):
        return None
    values, counts = np.unique(near, return_counts=True)
    return int(values[np.argmax(counts)])


def _solids(solids, lighting: Lighting) -> tuple[np.ndarray, np.ndarray]:
    from pilotlab.worlds.scene import normals
    if not solids:
        return np.zeros((0, 3, 3)), np.zeros((0, 3), np.uint8)
    triangles = np.concatenate([s.triangles for s in solids])
    base = np.concatenate([np.tile(s.colour, (len(s.triangles), 1)) for s in solids]).astype(float)
    shades = np.array([lighting.shade(n) for n in normals(triangles)])
    return triangles, np.clip(base * shades[:, None], 0, 255).astype(np.uint8)


def _store(world: BMWorld, entry: Path) -> None:
    """Write to a temporary folder, then rename: a cache entry is complete or absent."""
    entry.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=entry.parent, prefix=".building-"))
    try:
        arrays = {"colour": world.colour, "labels": world.labels, "solid_triangles": world.solid_triangles,
                  "solid_colours": world.solid_colours, "collision_triangles": world.collision_triangles}
        np.savez(staging / "arrays.npz", **arrays)
        for i, distance in enumerate(world.distances):   # memory-mapped when read
            np.save(staging / f"distance_{i}.npy", distance)
        (staging / "meta.json").write_text(json.dumps(world.meta, indent=1))
        try:
            staging.rename(entry)
        except OSError:  # another process stored it first: theirs is the same content
            shutil.rmtree(staging, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _read(entry: Path) -> BMWorld:
    meta = json.loads((entry / "meta.json").read_text())
    with np.load(entry / "arrays.npz", allow_pickle=False) as arrays:
        data = {key: arrays[key] for key in arrays.files}
    distances = [np.load(entry / f"distance_{i}.npy", mmap_mode="r") for i in range(len(meta["sharp"]))]
    return BMWorld(meta["name"], meta["digest"], Grid(**meta["grid"]), data["colour"], data["labels"], meta["sharp"],
                   distances, data["solid_triangles"], data["solid_colours"], data["collision_triangles"],
                   meta["layers"], meta)
