"""`pilotlab world list | show`: BehaviorMetrics' Gazebo worlds, and what the car's camera sees in them."""
from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

from pilotlab.errors import PilotlabError

ASSETS_HELP = ("BehaviorMetrics' worlds: a folder laid out like RoboticsInfrastructure/CustomRobots/f1 "
               "(worlds/ + models/); default $PILOTLAB_BM_ASSETS")


def register(subparsers) -> None:
    parser = subparsers.add_parser("world", help="list BehaviorMetrics' worlds and render what the car sees",
                                   description="BehaviorMetrics' Gazebo F1 worlds (docs/worlds.md): drive in them with "
                                               "--world on record/drive, or a recipe's world axis.")
    commands = parser.add_subparsers(dest="world_command", metavar="COMMAND", required=True)
    listing = commands.add_parser("list", help="the worlds of an assets folder")
    listing.add_argument("--assets", type=Path, default=None, help=ASSETS_HELP)
    listing.set_defaults(func=list_worlds)

    show = commands.add_parser("show", help="write the car camera's frame at a pose",
                               description="Write the full 640×480 camera frame (or with --view the network's "
                                           "200×66 input) with the car's origin at X,Y on the ground, heading YAW.")
    show.add_argument("world", help="world name: the .world file's stem (pilotlab world list)")
    show.add_argument("--assets", type=Path, default=None, help=ASSETS_HELP)
    show.add_argument("--pose", type=parse_pose, default=None,
                      help="X,Y,YAW: metres and radians in the world frame (default: the world's spawn pose)")
    # A pose starting with a minus (`--pose -200.8,-90.72,-2.83`, as `world list` prints spawn poses) is a
    # value, not an option: argparse tells a negative value from an option by this pattern (one number).
    show._negative_number_matcher = re.compile(r"^-\d*\.?\d+(e-?\d+)?(,-?\d*\.?\d+(e-?\d+)?)*$")
    show.add_argument("-o", "--out", type=Path, default=None, help="PNG to write (default: WORLD.png)")
    show.add_argument("--view", action="store_true", help="the network's input (lower half, 200×66) instead")
    show.add_argument("--renderer", choices=("ground", "pybullet"), default="ground",
                      help="ground: the fast renderer the laps use; pybullet: TinyRenderer over the meshes")
    show.add_argument("--own", action="store_true",
                      help="pilotlab's own world of the same circuit, with pilotlab's own camera, at the same pose")
    show.set_defaults(func=show_world)


def parse_pose(text: str) -> tuple[float, float, float]:
    try:
        x, y, yaw = (float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"pose {text!r}: give X,Y,YAW (metres, metres, radians), "
                                         "e.g. 53.462,-10.734,-1.57") from None
    if not all(map(math.isfinite, (x, y, yaw))):
        raise argparse.ArgumentTypeError(f"pose {text!r}: X, Y and YAW must be finite numbers")
    return x, y, yaw


def list_worlds(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table
    from pilotlab.worlds.assets import resolve_assets, world_names, world_path
    from pilotlab.worlds.sdf import read_world
    from pilotlab.worlds.world import circuit_of
    assets = resolve_assets(args.assets)
    table = Table(title=f"BehaviorMetrics worlds in {assets}")
    for column in ("world", "circuit", "sun", "walls", "camera (up, fov, clip)", "spawn (x, y, yaw)"):
        # a narrow terminal wraps the figures at their commas, a long one folds: never cut short with "…"
        table.add_column(column, no_wrap=column in ("world", "circuit"), overflow="fold")
    broken = []
    for name in world_names(assets):
        try:
            world = read_world(world_path(assets, name), assets)
        except PilotlabError as error:   # one broken world hides none of the others
            broken.append(str(error))
            table.add_row(name, "(broken: see below)", "", "", "", "")
            continue
        camera = world.camera
        optics = "-" if camera is None else (f"{camera.pose[2]:.2f} m, {math.degrees(camera.hfov_rad):.0f}°, "
                                             f"{camera.far_m:g} m")
        spawn = "-" if world.spawn is None else f"{world.spawn[0]:g}, {world.spawn[1]:g}, {world.spawn[5]:g}"
        table.add_row(name, _circuit(circuit_of, name, world.path), "yes" if world.sun else "no",
                      "yes" if world.collisions else "no", optics, spawn)
    console = Console()
    if not console.is_terminal:   # a pipe or a file has no width to fit: rich's 80 columns cut the poses short
        console = Console(width=160)
    console.print(table)
    for problem in broken:
        console.print(f"[bold red]broken[/]: {escape(problem)}", highlight=False)
    return 1 if broken else 0


def _circuit(circuit_of, name: str, path) -> str:
    try:
        return Path(circuit_of(name, path)).name
    except PilotlabError:
        return "(none)"


def show_world(args: argparse.Namespace) -> int:
    import cv2
    from pilotlab.worlds import load_world
    world = load_world(args.world, args.assets)
    pose = args.pose or _spawn_pose(world)
    image = render_at(world, pose, view=args.view, renderer=args.renderer, own=args.own)
    out = args.out or Path(f"{args.world}{'_own' if args.own else ''}.png")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        written = cv2.imwrite(str(out), image[:, :, ::-1])
    except (OSError, cv2.error) as error:
        written, reason = False, getattr(error, "strerror", None) or str(error).splitlines()[-1]
        if (in_the_way := next((p for p in reversed(out.parents) if p.exists() and not p.is_dir()), None)):
            reason = f"{in_the_way} is a file, not a folder"   # it said "(File exists)" (outside test)
    else:
        reason = "OpenCV could not write it"
    if not written:
        raise PilotlabError(f"cannot write {out} ({reason}): give a .png path in a writable folder")
    what = "pilotlab's own world" if args.own else f"world {args.world}"
    print(f"{what} at x={pose[0]:g}, y={pose[1]:g}, yaw={pose[2]:g}: {image.shape[1]}×{image.shape[0]} "
          f"{'network view' if args.view else 'camera frame'} written to {out}", flush=True)
    if args.pose is not None and (far := _far_from_the_road(world, pose)):
        print(f"note: {far}", file=sys.stderr)
    return 0


FAR_FROM_THE_ROAD_M = 50.0   # a camera this far from the centreline sees grass and sky, or nothing of the world


def _far_from_the_road(world, pose) -> str | None:
    """Outside test: a pose off the map rendered sky without a word. None where the pose is near the road
    (or the world has no centreline to measure from)."""
    try:
        nearest = world.circuit().project(pose[0], pose[1])
    except PilotlabError:
        return None
    distance = abs(nearest.lateral)
    if distance <= FAR_FROM_THE_ROAD_M:
        return None
    return (f"x={pose[0]:g}, y={pose[1]:g} is {distance:,.0f} m from the road (its nearest centreline point is at "
            f"x={nearest.x:.1f}, y={nearest.y:.1f}), so the frame shows little or none of the track; `pilotlab world "
            f"list` prints each world's spawn pose")


def _spawn_pose(world) -> tuple[float, float, float]:
    if world.spawn is None:
        raise PilotlabError(f"world {world.name} has no car spawn pose; give --pose X,Y,YAW")
    return world.spawn[0], world.spawn[1], world.spawn[5]


def render_at(world, pose, *, view: bool = False, renderer: str = "ground", own: bool = False):
    """The camera frame (or the network's view) with the car's origin at `pose` on the ground."""
    from pilotlab.data.preprocess import PreprocessConfig, preprocess
    from pilotlab.sim.camera import CameraSpec, camera_pose
    x, y, yaw = pose
    quaternion = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    camera = CameraSpec() if own else world.camera()
    eye, rotation = camera_pose(camera, (x, y, 0.0), quaternion, 0.0)
    image = _renderer(world, camera, renderer, own).render(eye, rotation)
    return preprocess(image, PreprocessConfig()) if view else image


def _renderer(world, camera, name: str, own: bool):
    if own and name == "ground":
        from pilotlab.sim.render import GroundRenderer
        return GroundRenderer(world.circuit(), camera)
    if own:   # pilotlab's own world in pybullet, as a lap with `renderer: pybullet` sees it (it was ignored)
        from pilotlab.sim.render import PybulletRenderer
        from pilotlab.sim.world import World
        own_world = World(world.circuit().directed("cw"))
        renderer = PybulletRenderer(own_world.client, camera)
        renderer.world = own_world   # its client lives as long as the renderer
        return renderer
    if name == "ground":
        from pilotlab.worlds.render import WorldRenderer
        return WorldRenderer(world, camera)
    from pilotlab.sim.bullet import p
    from pilotlab.worlds.bullet import add_visuals
    from pilotlab.worlds.render import BulletWorldRenderer
    client = p.connect(p.DIRECT)
    add_visuals(client, world)
    return BulletWorldRenderer(client, camera)
