"""COLLADA meshes read with trimesh + pycollada, in metres, in the world frame.

trimesh reads the geometry, node transforms, materials and textures; the file's `<unit meter=...>`
and `<up_axis>` are read from its XML here, strictly (trimesh records units but does not apply them,
and SketchUp exports in inches). A missing texture, an unknown unit or a damaged file is a one-line
error naming the file.
"""
from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from pilotlab.errors import PilotlabError
from pilotlab.worlds.sdf import Mesh, parse_xml

NS = "{http://www.collada.org/2005/11/COLLADASchema}"
UP_AXES = {"Z_UP": np.eye(3), "Y_UP": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
           "X_UP": np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])}


@dataclass(frozen=True)
class Part:
    """Triangles of one material: world metres (n, 3, 3), the material's RGB (0-255), and its texture
    (an RGB array) with per-corner texture coordinates (n, 3, 2) when it has one."""
    triangles: np.ndarray = field(repr=False)
    colour: tuple[int, int, int]
    texture: np.ndarray | None = field(default=None, repr=False)
    uv: np.ndarray | None = field(default=None, repr=False)
    texture_name: str | None = None
    source: str = ""


def unit_and_axis(root: ET.Element, path: Path) -> tuple[float, np.ndarray]:
    asset = root.find(f"{NS}asset")
    unit = asset.find(f"{NS}unit") if asset is not None else None
    metres = 1.0
    if unit is not None:
        try:
            metres = float(unit.get("meter", "1"))
        except ValueError:
            metres = float("nan")
        if not (metres > 0 and np.isfinite(metres)):
            raise PilotlabError(f"{path}: unknown unit {unit.get('name')!r} (meter={unit.get('meter')!r}); "
                                "COLLADA's <unit meter=...> must be a positive number of metres")
    axis = (asset.findtext(f"{NS}up_axis") if asset is not None else None) or "Y_UP"
    if axis.strip() not in UP_AXES:
        raise PilotlabError(f"{path}: unknown <up_axis> {axis!r}; expected one of {', '.join(UP_AXES)}")
    return metres, UP_AXES[axis.strip()]


def texture_files(path: Path, root: ET.Element | None = None) -> list[Path]:
    """The image files the COLLADA file names (beside it, as Gazebo finds them); a missing one is an error."""
    root = parse_xml(path) if root is None else root
    found = []
    for image in root.iter(f"{NS}image"):
        name = unquote((image.findtext(f"{NS}init_from") or "").strip())
        if not name:
            continue
        for candidate in (path.parent / name, path.parent / Path(name).name):
            if candidate.is_file():
                found.append(candidate)
                break
        else:
            raise PilotlabError(f"{path}: texture {name!r} is missing (looked for {path.parent / name})")
    return found


def check_images(files: list[Path], mesh: Path) -> None:
    """Each texture decodes: one that does not, trimesh leaves out without a word (the ground of a world
    turned grey), so the world would not be BM's."""
    from PIL import Image
    for file in files:
        try:
            with Image.open(file) as image:
                image.load()
        except (OSError, SyntaxError, ValueError) as error:
            raise PilotlabError(f"{file}: a texture of {mesh.name} that cannot be read as an image ({error}); "
                                "restore it from BehaviorMetrics' worlds") from None


def read_mesh(mesh: Mesh) -> list[Part]:
    """The mesh's triangles in world metres, one Part per material and texture."""
    root = parse_xml(mesh.path)
    if root.tag != f"{NS}COLLADA":
        raise PilotlabError(f"{mesh.path}: not a COLLADA 1.4 file (root element {root.tag!r})")
    metres, up = unit_and_axis(root, mesh.path)
    check_images(texture_files(mesh.path, root), mesh.path)
    to_world = mesh.transform.copy()
    to_world[:3, :3] = to_world[:3, :3] @ up * metres
    parts = []
    for piece in _load_scene(mesh.path).dump(concatenate=False):
        if len(piece.faces):
            parts.append(_part(piece, to_world, mesh.path))
    return merge_parts(parts)


def _load_scene(path: Path):
    import trimesh  # imported here: only world import needs it
    logging.getLogger("trimesh").setLevel(logging.ERROR)
    try:
        return trimesh.load(str(path), force="scene")
    except Exception as error:  # pycollada raises many kinds: each one means the file is damaged
        raise PilotlabError(f"{path}: cannot read the COLLADA file ({type(error).__name__}: "
                            f"{str(error).splitlines()[0] if str(error) else 'damaged'})") from None


def _part(piece, to_world: np.ndarray, path: Path) -> Part:
    vertices = piece.vertices @ to_world[:3, :3].T + to_world[:3, 3]
    triangles = vertices[piece.faces]
    material = getattr(piece.visual, "material", None)
    colour = (200, 200, 200)
    texture = uv = name = None
    if material is not None:
        factor = getattr(material, "baseColorFactor", None)
        if factor is None and getattr(material, "diffuse", None) is not None:
            factor = material.diffuse
        if factor is not None:
            colour = tuple(int(c) for c in np.asarray(factor)[:3])
        image = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
        coords = getattr(piece.visual, "uv", None)
        if image is not None and coords is not None and len(coords) == len(piece.vertices):
            texture = np.asarray(image.convert("RGB"))
            uv, name = np.asarray(coords, dtype=np.float64)[piece.faces], getattr(material, "name", None)
    return Part(triangles, colour, texture, uv, name, path.name)


def merge_parts(parts: list[Part]) -> list[Part]:
    """One Part per look (colour + texture): SketchUp splits a material over many geometries."""
    groups: dict[tuple, list[Part]] = {}
    for part in parts:
        key = (part.colour, None if part.texture is None else (part.texture.shape, part.texture[::17, ::17].tobytes()))
        groups.setdefault(key, []).append(part)
    merged = []
    for group in groups.values():
        first = group[0]
        uv = None if first.uv is None else np.concatenate([g.uv for g in group])
        merged.append(Part(np.concatenate([g.triangles for g in group]), first.colour, first.texture, uv,
                           first.texture_name, first.source))
    return merged
