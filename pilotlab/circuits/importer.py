"""Building a circuit from a recorded lap in a rosbag, the way BehaviorMetrics keeps its "perfect lap"
files: the positions of nav_msgs/Odometry or geometry_msgs/PoseStamped messages on one topic, cut to
one lap, saved as a CSV of x, y points that the circuit registry reads.

Where it goes: `circuits/NAME.csv` under the working directory by default (`--out-dir` to change);
a circuit in `./circuits/` (or in a folder listed in $PILOTLAB_CIRCUITS) is then known by its NAME to
`pilotlab record --circuit NAME`, to recipes and to `pilotlab circuit list`; from anywhere else give
the CSV's path instead of the name.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from pilotlab.circuits.circuit import Circuit
from pilotlab.circuits.geometry import close_loop, drop_repeats, polyline_length
from pilotlab.circuits.registry import CIRCUITS, DEFAULT_ROAD_WIDTH_M, DEFAULT_USER_DIR
from pilotlab.errors import BagError, PilotlabError

POSE_TYPES = {
    "nav_msgs/msg/Odometry": lambda m: m.pose.pose.position,
    "geometry_msgs/msg/PoseStamped": lambda m: m.pose.position,
    "geometry_msgs/msg/PoseWithCovarianceStamped": lambda m: m.pose.pose.position,
}
MIN_STEP_M = 0.05  # positions closer than this to the previous one are dropped (the car stood still)
MAX_CLOSING_GAP = 0.05  # a path that ends further than this share of its length from its start is no lap


def read_positions(bag: Path, topic: str) -> np.ndarray:
    """x, y of every pose message on `topic` of a ROS1 bag file or ROS2 bag folder, in time order."""
    bag = Path(bag)
    if not bag.exists():
        raise BagError(f"{bag}: no such bag (a ROS1 .bag file or a ROS2 bag folder)")
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            connections = [c for c in reader.connections if c.topic == topic]
            if not connections:
                present = ", ".join(sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections)) or "none"
                raise BagError(f"{bag}: no topic {topic!r}; topics present: {present}")
            msgtype = connections[0].msgtype
            if msgtype not in POSE_TYPES:
                raise BagError(f"{bag}: topic {topic} carries {msgtype}; a circuit needs positions from one of: "
                               f"{', '.join(POSE_TYPES)}")
            position = POSE_TYPES[msgtype]
            points = [(p.x, p.y) for p in (position(reader.deserialize(raw, c.msgtype))
                                           for c, _, raw in reader.messages(connections=connections))]
    except BagError:
        raise
    except Exception as error:  # rosbags raises several types for a truncated or foreign file
        raise BagError(f"{bag}: cannot read it as a ROS1 or ROS2 bag ({type(error).__name__}: {error})") from None
    return np.array(points, dtype=np.float64).reshape(-1, 2)


def lap_from_positions(points: np.ndarray, source: str) -> np.ndarray:
    """One lap of the recorded path: standstill points dropped, cut where it first comes back to its
    start (a recording that stops just short is closed with a straight segment; one that ends far
    from its start is part of a lap, and a straight segment would cut across the circuit)."""
    points = drop_repeats(points, MIN_STEP_M)
    if len(points) < 10 or polyline_length(points) < 20.0:
        raise PilotlabError(f"{source}: the recorded path is too short for a circuit "
                            f"({len(points)} distinct positions, {polyline_length(points):.1f} m); record a whole lap")
    lap = close_loop(points)
    gap, length = float(np.linalg.norm(lap[-1] - lap[0])), polyline_length(lap)
    if gap > MAX_CLOSING_GAP * length:
        raise PilotlabError(f"{source}: the recorded path does not come back to its start (it ends {gap:.1f} m "
                            f"from it after {length:.1f} m), so it holds no whole lap; record a whole lap")
    return lap


def import_circuit(bag: Path, topic: str, name: str, out_dir: Path = DEFAULT_USER_DIR,
                   overwrite: bool = False) -> tuple[Path, Circuit]:
    """Read a lap from `bag`/`topic` and save it as `out_dir/NAME.csv`; returns the path and circuit."""
    if name in CIRCUITS:
        raise PilotlabError(f"{name!r} is a built-in circuit; import under another name")
    if not name or any(c in name for c in "/\\ ") or name.startswith("."):
        raise PilotlabError(f"circuit name {name!r} must be a plain file name (no spaces or slashes)")
    path = Path(out_dir) / f"{name}.csv"
    if path.exists() and not overwrite:
        raise PilotlabError(f"{path} already exists; pick another name or pass --force to replace it")
    source = f"{bag} {topic}"
    lap = lap_from_positions(read_positions(bag, topic), source)
    circuit = Circuit.from_points(name, lap, road_width=DEFAULT_ROAD_WIDTH_M, source=str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [f"# circuit {name}: imported by pilotlab from {bag} (topic {topic})", "x_m,y_m"]
    lines += [f"{x:.4f},{y:.4f}" for x, y in lap]
    tmp = path.with_suffix(".csv.tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(path)
    return path, circuit
