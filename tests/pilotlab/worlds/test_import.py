"""Reading a world: units, transforms, textures, lighting, the cache, and damaged files."""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

from pilotlab.errors import PilotlabError
from pilotlab.worlds import load_world
from pilotlab.worlds.assets import resolve_assets, world_names
from pilotlab.worlds.collada import read_mesh
from pilotlab.worlds.sdf import read_world
from tests.pilotlab.worlds.synthetic import LINE_M, ROAD_M, centreline, write_world


def test_world_names_and_parse(oval_assets):
    assert world_names(oval_assets) == ["oval", "oval_no_sun"]
    parsed = read_world(oval_assets / "worlds" / "oval.world", oval_assets)
    assert parsed.camera.hfov_rad == pytest.approx(1.57) and parsed.camera.far_m == 15
    assert parsed.camera.pose[:3] == (0.45, 0.04, 0.1)
    assert parsed.sun is not None and parsed.sky
    assert read_world(oval_assets / "worlds" / "oval_no_sun.world", oval_assets).sun is None


def test_inches_node_transform_and_model_pose_land_the_line_on_the_centreline(oval_assets):
    """The mesh is in inches under a node translation inside a model placed with a pose: read right, its red
    line lies on the centreline (written in world metres)."""
    parsed = read_world(oval_assets / "worlds" / "oval.world", oval_assets)
    parts = read_mesh(parsed.visuals[0])
    red = next(part for part in parts if part.colour == (255, 0, 0))
    centres = red.triangles.mean(axis=1)[:, :2]
    points = centreline()
    distance = np.min(np.linalg.norm(centres[:, None] - points[None], axis=2), axis=1)   # points 0.1 m apart
    assert np.median(distance) < 0.04 and distance.max() < 0.08
    assert red.triangles[:, :, 2].max() == pytest.approx(0.002, abs=1e-4)
    road = next(part for part in parts if part.texture is not None)
    assert road.texture.shape == (64, 64, 3) and road.uv is not None


def test_world_layers_line_road_width_and_lighting(oval_assets):
    world = load_world("oval", oval_assets)
    assert world.line_colour == (255, 0, 0)
    assert world.road_width == pytest.approx(ROAD_M, abs=0.2)
    assert len(world.collision_triangles) > 0 and world.has_sun
    assert world.circuit().length == pytest.approx(2 * 20 + 2 * math.pi * 8, rel=0.01)
    dark = load_world("oval_no_sun", oval_assets)
    ground = world.labels > 0
    assert dark.colour[ground].mean() < world.colour[ground].mean() * 0.6   # no sun: only the ambient light
    camera = world.camera()
    assert camera.level and camera.height_m == pytest.approx(0.104) and camera.lateral_m == 0.04


def test_the_road_is_measured_where_the_grass_is_smaller_than_the_road(tmp_path):
    """Outside test: BM's many_curves has more asphalt than grass; the largest layer was taken for the grass
    and its road measured 0.175 m (the red line), so every lap left the road at once."""
    world = load_world("oval", write_world(tmp_path / "assets", grass_beside=0.8))
    assert world.road_width == pytest.approx(ROAD_M, abs=0.2)


def test_a_damaged_cache_entry_is_built_again(oval_assets, tmp_path, monkeypatch):
    """Outside test: a truncated arrays.npz or meta.json (a full disk, a partial copy) was a traceback."""
    monkeypatch.setenv("PILOTLAB_CACHE", str(tmp_path / "cache"))
    first = load_world("oval", oval_assets)
    entry = next((tmp_path / "cache").glob("**/arrays.npz")).parent
    (entry / "arrays.npz").write_bytes((entry / "arrays.npz").read_bytes()[:100])
    assert load_world("oval", oval_assets).road_width == first.road_width
    (entry / "meta.json").write_text("{")
    assert load_world("oval", oval_assets).digest == first.digest


def test_cache_is_keyed_by_content(oval_assets, tmp_path):
    copy = shutil.copytree(oval_assets, tmp_path / "assets")
    first = load_world("oval", copy)
    assert load_world("oval", copy).digest == first.digest       # same files: same entry
    texture = copy / "models" / "oval" / "meshes" / "asphalt.png"
    texture.write_bytes(texture.read_bytes() + b"\0")              # any edit: a new entry
    assert load_world("oval", copy).digest != first.digest


@pytest.mark.parametrize("damage, message", [
    (lambda root: (root / "models/oval/meshes/walls.dae").unlink(), "walls.dae is missing"),
    (lambda root: (root / "models/oval/meshes/track.dae").write_text("<COLLADA><asset>"), "track.dae: not valid XML"),
    (lambda root: (root / "models/oval/meshes/asphalt.png").unlink(), "texture 'asphalt.png' is missing"),
    # outside test: a texture that does not decode was left out by trimesh, the road drawn in grey
    (lambda root: (root / "models/oval/meshes/asphalt.png").write_bytes(b"\x89PNG garbage"),
     "asphalt.png: a texture of track.dae that cannot be read as an image"),
    (lambda root: _edit(root / "models/oval/meshes/track.dae", 'meter="0.0254"', 'meter="inch"'), "unknown unit"),
    (lambda root: _edit(root / "worlds/oval.world", "model://oval<", "model://ovall<"), "does not exist"),
    (lambda root: _edit(root / "worlds/oval.world", '<pose>2.000000', '<pose>two'), "expected 6 numbers"),
])
def test_damaged_assets_are_one_line_errors_naming_the_file(oval_assets, tmp_path, damage, message):
    copy = shutil.copytree(oval_assets, tmp_path / "assets")
    damage(copy)
    with pytest.raises(PilotlabError, match=message) as error:
        load_world("oval", copy)
    assert "\n" not in str(error.value) and str(copy) in str(error.value)


def _edit(path, old, new):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))


def test_assets_folder_errors(tmp_path, monkeypatch):
    monkeypatch.delenv("PILOTLAB_BM_ASSETS", raising=False)
    with pytest.raises(PilotlabError, match="--assets"):
        resolve_assets(None)
    with pytest.raises(PilotlabError, match="no worlds/ folder"):
        resolve_assets(tmp_path)


def test_unknown_world_says_did_you_mean(oval_assets):
    with pytest.raises(PilotlabError, match="did you mean 'oval'"):
        load_world("ovl", oval_assets)


def test_bm_simple_circuit_facts(bm_assets):
    """The README's facts, read by the importer: units per file, the spawn pose, the camera, the sun."""
    world = load_world("simple_circuit", bm_assets)
    assert world.spawn == (53.462, -10.734, 0.004, 0.0, 0.0, -1.57)
    assert world.line_colour == (255, 0, 0) and world.has_sun
    assert 3.0 < world.road_width < 4.0
    assert world.camera().far_m == 15 and world.camera().hfov_deg == pytest.approx(math.degrees(1.57))
    assert load_world("simple_circuit_white_line", bm_assets).line_colour == (255, 255, 255)
    assert not load_world("simple_circuit_no_sun", bm_assets).has_sun
    assert len(load_world("simple_circuit_no_wall", bm_assets).collision_triangles) == 0
