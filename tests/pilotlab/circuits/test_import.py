import numpy as np
import pytest
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

from pilotlab.circuits.load import get_circuit
from pilotlab.circuits.importer import import_circuit, read_positions
from pilotlab.cli import main
from pilotlab.errors import BagError, PilotlabError
from pilotlab.sim.record import RecordSpec, record
from tests.pilotlab.tracks import stadium


def record_lap(circuit: str, out, format: str):
    spec = RecordSpec(circuit=circuit, camera={"width": 32, "height": 24}, rate_hz=1.0, format=format)
    return record(spec, out)


@pytest.mark.parametrize("format", ["ros1", "ros2"])
def test_a_circuit_imported_from_a_recorded_lap_has_the_original_length(stadium_csv, tmp_path, format):
    summary = record_lap(stadium_csv, tmp_path / "lap", format)
    assert summary.termination == "lap_completed"
    path, circuit = import_circuit(summary.path, "/F1ROS/odom", "copy", out_dir=tmp_path / "circuits")
    original = get_circuit(stadium_csv)
    assert path == tmp_path / "circuits" / "copy.csv"
    assert abs(circuit.length - original.length) < 0.01 * original.length
    # The copy is the same loop: every point of it lies on the original's road, near the red line.
    assert max(original.project(x, y).distance for x, y in circuit.points[::10]) < 0.3
    assert get_circuit(str(path)).length == pytest.approx(circuit.length)


def write_pose_stamped_bag(path, points):
    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    with Writer(path, version=8) as writer:
        connection = writer.add_connection("/lap/pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        for i, (x, y) in enumerate(points):
            header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=i, nanosec=0),
                                                  frame_id="map")
            pose = types["geometry_msgs/msg/Pose"](position=types["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                                   orientation=types["geometry_msgs/msg/Quaternion"](x=0, y=0, z=0, w=1))
            message = types["geometry_msgs/msg/PoseStamped"](header=header, pose=pose)
            writer.write(connection, i * 10**9, store.serialize_cdr(message, connection.msgtype))


def test_pose_stamped_laps_that_overrun_the_start_are_cut_to_one_lap(tmp_path):
    points = stadium()
    overrun = np.concatenate([points[:3], points, points[:80]])  # standing at the start, then 16 m too far
    write_pose_stamped_bag(tmp_path / "poses", overrun)
    assert len(read_positions(tmp_path / "poses", "/lap/pose")) == len(overrun)
    _, circuit = import_circuit(tmp_path / "poses", "/lap/pose", "poses", out_dir=tmp_path)
    assert circuit.length == pytest.approx(get_circuit(str(tmp_path / "poses.csv")).length)
    assert abs(circuit.length - 110.27) < 1.1


def test_import_errors_name_the_bag_and_the_topics(tmp_path):
    write_pose_stamped_bag(tmp_path / "poses", stadium())
    with pytest.raises(BagError, match=r"no topic '/odom'; topics present: /lap/pose \(geometry_msgs/msg/PoseStamped\)"):
        read_positions(tmp_path / "poses", "/odom")
    with pytest.raises(BagError, match="no such bag"):
        read_positions(tmp_path / "missing.bag", "/odom")
    (tmp_path / "junk.bag").write_bytes(b"not a bag at all")
    with pytest.raises(BagError, match="junk.bag: cannot read it"):
        read_positions(tmp_path / "junk.bag", "/odom")
    with pytest.raises(PilotlabError, match="built-in"):
        import_circuit(tmp_path / "poses", "/lap/pose", "montreal", out_dir=tmp_path)
    with pytest.raises(PilotlabError, match="too short"):
        write_pose_stamped_bag(tmp_path / "short", stadium()[:5])
        import_circuit(tmp_path / "short", "/lap/pose", "short", out_dir=tmp_path)


def test_part_of_a_lap_is_refused_and_a_lap_stopping_just_short_is_closed(tmp_path):
    points = stadium()
    write_pose_stamped_bag(tmp_path / "part", points[: len(points) * 4 // 5])
    with pytest.raises(PilotlabError, match=r"does not come back to its start \(it ends .* m from it"):
        import_circuit(tmp_path / "part", "/lap/pose", "part", out_dir=tmp_path)
    write_pose_stamped_bag(tmp_path / "almost", points[:-5])     # 1.2 m short of the start
    _, circuit = import_circuit(tmp_path / "almost", "/lap/pose", "almost", out_dir=tmp_path)
    assert abs(circuit.length - 110.27) < 1.1


def test_cli_import_saves_under_circuits_and_the_name_then_works(tmp_path, monkeypatch, capsys):
    write_pose_stamped_bag(tmp_path / "poses", stadium())
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PILOTLAB_CIRCUITS", raising=False)
    assert main(["circuit", "import", "poses", "--topic", "/lap/pose", "--name", "oval"]) == 0
    out = capsys.readouterr().out
    assert "saved to circuits/oval.csv" in out and "--circuit oval" in out
    assert main(["circuit", "import", "poses", "--topic", "/lap/pose", "--name", "oval"]) == 2  # exists
    assert "--force" in capsys.readouterr().err
    assert main(["circuit", "list"]) == 0
    listing = capsys.readouterr().out
    assert "oval" in listing and "circuits/oval.csv" in listing and "1426.5" in listing
    assert main(["circuit", "show", "oval", "-o", "oval.png"]) == 0
    assert (tmp_path / "oval.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
@pytest.mark.parametrize("format", ["ros1", "ros2"])
def test_simple_circuit_imported_from_a_recorded_lap_has_its_length(tmp_path, format):
    summary = record_lap("simple_circuit", tmp_path / "lap", format)
    _, circuit = import_circuit(summary.path, "/F1ROS/odom", "simple_copy", out_dir=tmp_path)
    original = get_circuit("simple_circuit")
    print(f"\nimported simple_circuit ({format}): {circuit.length:.2f} m vs {original.length:.2f} m "
          f"({100 * (circuit.length / original.length - 1):+.2f} %)")
    assert abs(circuit.length - original.length) < 0.01 * original.length
