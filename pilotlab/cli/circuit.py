"""`pilotlab circuit list | show | import`: the circuits the simulator knows, their maps, new ones from bags."""
from __future__ import annotations

import argparse
from pathlib import Path

from pilotlab.errors import PilotlabError


def register(subparsers) -> None:
    parser = subparsers.add_parser("circuit", help="list, draw and import circuits",
                                   description="Circuits: the five JdeRobot follow-line circuits, plus user circuits "
                                               "(NAME.csv in ./circuits/ or $PILOTLAB_CIRCUITS, or any CSV path).")
    commands = parser.add_subparsers(dest="circuit_command", metavar="COMMAND", required=True)

    listing = commands.add_parser("list", help="the known circuits with their lengths")
    listing.set_defaults(func=list_circuits)

    show = commands.add_parser("show", help="draw a circuit's map")
    show.add_argument("name", help="circuit name or CSV path")
    show.add_argument("-o", "--out", type=Path, default=None, help="image file to write (default: NAME.png)")
    show.add_argument("--direction", choices=("cw", "ccw"), default="cw")
    show.set_defaults(func=show_circuit)

    importing = commands.add_parser(
        "import", help="make a circuit from a recorded lap in a ROS1/ROS2 bag",
        description="Read the positions of a lap (nav_msgs/Odometry or geometry_msgs/PoseStamped) from a bag, "
                    "cut them to one lap and save them as OUT_DIR/NAME.csv. Circuits in ./circuits/ (the default "
                    "OUT_DIR) or in a folder of $PILOTLAB_CIRCUITS are then known by NAME everywhere "
                    "(--circuit NAME, recipes, `pilotlab circuit list`); elsewhere, give the CSV path instead.")
    importing.add_argument("bag", type=Path, help="a ROS1 .bag file or a ROS2 bag folder")
    importing.add_argument("--topic", required=True, help="topic with the positions, e.g. /F1ROS/odom")
    importing.add_argument("--name", required=True, help="name of the new circuit")
    importing.add_argument("--out-dir", type=Path, default=Path("circuits"), help="folder to save NAME.csv in")
    importing.add_argument("--force", action="store_true", help="replace an existing NAME.csv")
    importing.set_defaults(func=import_from_bag)


def list_circuits(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text
    from pilotlab.circuits import CIRCUITS, all_circuit_names, csv_path_of
    from pilotlab.circuits.load import get_circuit
    table = Table(title="circuits")
    for column in ("name", "length (m)", "road (m)", "timeout (s)", "source"):
        table.add_column(column, justify="right" if "(" in column else "left")
    broken = []
    for name in all_circuit_names():
        source = "built-in" if name in CIRCUITS else str(csv_path_of(name))
        try:
            circuit = get_circuit(name)
        except PilotlabError as error:   # one bad CSV in ./circuits/ does not hide the good ones
            table.add_row(Text(name, style="red"), "-", "-", "-", Text(source))
            broken.append(str(error))
            continue
        table.add_row(Text(name), f"{circuit.length:.1f}", f"{circuit.road_width:g}", f"{circuit.timeout_s:.1f}",
                      Text(source))
    console = Console()
    console.print(table)
    for problem in broken:
        console.print(f"cannot be driven: {problem}", style="red", markup=False, highlight=False)
    return 1 if broken else 0


def show_circuit(args: argparse.Namespace) -> int:
    from pilotlab.circuits.draw import draw_map
    from pilotlab.circuits.lookup import load_named
    circuit = load_named(args.name, args.direction)
    path = draw_map(circuit, _map_path(args.out, circuit.name))
    print(f"{circuit.name} ({circuit.direction}, {circuit.length:.1f} m): map written to {path}")
    return 0


def _map_path(out: Path | None, name: str) -> Path:
    """Where `-o` puts the map: NAME.png by default or inside a folder given; a file name without a
    suffix gets .png (what is written is what is printed); a suffix matplotlib cannot write is refused."""
    from matplotlib.backend_bases import FigureCanvasBase
    if out is None or out.is_dir():
        return (out or Path()) / f"{name}.png"
    if not out.suffix:
        return out.with_suffix(".png")
    formats = FigureCanvasBase.get_supported_filetypes()
    if out.suffix[1:].lower() not in formats:
        raise PilotlabError(f"-o {out}: cannot write a {out.suffix} image; give one of "
                            f"{', '.join('.' + f for f in sorted(formats))}")
    return out


def import_from_bag(args: argparse.Namespace) -> int:
    from pilotlab.circuits.importer import import_circuit
    path, circuit = import_circuit(args.bag, args.topic, args.name, args.out_dir, overwrite=args.force)
    print(f"circuit {circuit.name!r}: {circuit.length:.1f} m, saved to {path}")
    if path.parent.resolve() == Path("circuits").resolve():
        print(f"use it from this folder as --circuit {circuit.name} (or in a recipe: circuits: [{circuit.name}])")
    else:
        print(f"use it as --circuit {path}, or add {path.parent} to $PILOTLAB_CIRCUITS to use the name "
              f"{circuit.name}")
    return 0
