import math

import numpy as np
import pytest

from matrix.registry import DuplicateNameError
from pilotlab.circuits import CIRCUITS, CircuitConfig
from pilotlab.circuits.load import get_circuit, read_points_csv
from pilotlab.circuits.circuit import Circuit
from pilotlab.circuits.geometry import close_loop, polyline_length
from pilotlab.circuits.registry import builtin_csv
from pilotlab.errors import PilotlabError
from tests.pilotlab.tracks import stadium, stadium_length, write_csv

FIVE = ["simple_circuit", "many_curves", "montmelo", "montreal", "nurburgring"]
TIMEOUTS = {"simple_circuit": 82.5, "many_curves": 166.1, "montmelo": 134.2, "montreal": 272.8, "nurburgring": 96.8}


def test_the_five_jderobot_circuits_are_registered_with_their_timeouts():
    assert CIRCUITS.names() == FIVE
    for name in FIVE:
        assert get_circuit(name).timeout_s == TIMEOUTS[name]


@pytest.mark.parametrize("name", FIVE)
def test_builtin_centrelines_stay_on_the_published_laps(name):
    circuit = get_circuit(name)
    raw = read_points_csv(builtin_csv(CIRCUITS.get(name)))
    # The published points lie on a 0.13 m (montreal 0.33 m) grid: the raw staircase over-counts the
    # length by up to 8 %, the smoothed line is shorter but follows every point within 0.7 m.
    assert 0.90 * polyline_length(raw) < circuit.length < polyline_length(raw)
    distances = [circuit.project(x, y).distance for x, y in raw[::7]]
    assert np.mean(distances) < 0.12 and max(distances) < 0.7
    spacing = np.linalg.norm(np.diff(np.vstack([circuit.points, circuit.points[:1]]), axis=0), axis=1)
    assert spacing.max() < 0.3 and spacing.min() > 0.2


def test_many_curves_is_closed_where_its_recording_passes_the_start_again():
    raw = read_points_csv(builtin_csv(CIRCUITS.get("many_curves")))
    lap = close_loop(raw)
    assert len(lap) < len(raw)  # the recording overruns its start by about 11 m: cut there
    assert np.linalg.norm(lap[-1] - lap[0]) < 0.5
    circuit = get_circuit("many_curves")
    assert np.linalg.norm(circuit.points[-1] - circuit.points[0]) < 0.3
    assert np.max(np.abs(circuit.curvature)) < 0.5  # no kink at the join


def test_lateral_offset_is_positive_to_the_left_of_the_driving_direction(stadium_csv):
    cw = get_circuit(stadium_csv)
    x, y, yaw = cw.start_pose()
    assert (x, y) == pytest.approx((0.0, 8.0), abs=0.05) and yaw == pytest.approx(0.0, abs=0.01)
    # Clockwise, the top straight is driven east: north (outside) is on the left.
    assert cw.project(3.0, 9.0).lateral == pytest.approx(1.0, abs=0.02)
    assert cw.project(3.0, 7.5).lateral == pytest.approx(-0.5, abs=0.02)
    ccw = get_circuit(stadium_csv, "ccw")
    assert ccw.start_pose()[:2] == pytest.approx((x, y), abs=1e-9)
    assert abs(math.remainder(ccw.start_pose()[2] - math.pi, 2 * math.pi)) < 0.01
    assert ccw.project(3.0, 9.0).lateral == pytest.approx(-1.0, abs=0.02)


def test_arc_length_wraps_and_matches_the_geometry(stadium_csv):
    circuit = get_circuit(stadium_csv)
    assert circuit.length == pytest.approx(stadium_length(), rel=0.01)
    assert circuit.point_at(circuit.length + 5.0) == pytest.approx(circuit.point_at(5.0))
    x, y = circuit.point_at(10.0)
    projection = circuit.project(x, y)
    assert projection.s == pytest.approx(10.0, abs=0.01) and projection.distance < 1e-6
    assert circuit.heading_at(10.0) == pytest.approx(0.0, abs=0.01)  # still on the top straight
    # The bends turn right (clockwise) at about 1 / 8 m.
    assert circuit.curvature_at(15.0 + 4 * math.pi) == pytest.approx(-1 / 8, rel=0.1)
    # Windowed search finds the same point as the full one, and ignores far-away road.
    assert circuit.project(x, y + 0.5, near_s=12.0, window=10.0) == circuit.project(x, y + 0.5)


def test_a_counter_clockwise_csv_becomes_the_same_clockwise_circuit(tmp_path):
    points = stadium()
    reverse = np.roll(points[::-1], 1, axis=0)
    cw = Circuit.from_points("a", points, road_width=6.0)
    from_ccw = Circuit.from_points("b", reverse, road_width=6.0)
    assert from_ccw.length == pytest.approx(cw.length, rel=1e-3)
    # Driven ccw, the arc length follows the CSV's own order again.
    assert from_ccw.directed("ccw").project(*reverse[50]).s == pytest.approx(polyline_length(reverse[:51]), abs=0.3)
    assert cw.directed("ccw").directed("cw") is cw


def test_unknown_circuit_names_the_known_ones():
    with pytest.raises(PilotlabError, match=r"did you mean 'montreal'.*simple_circuit"):
        get_circuit("montrael")
    with pytest.raises(PilotlabError, match="direction"):
        get_circuit("montreal", "clockwise")


def test_registering_a_circuit_twice_is_an_error():
    with pytest.raises(DuplicateNameError):
        CIRCUITS.add("montreal", CircuitConfig("montreal", "montreal.csv", 1.0))


def test_user_circuits_are_found_by_name_in_the_user_folders(tmp_path, monkeypatch):
    folder = tmp_path / "mine"
    folder.mkdir()
    text = "# my track\nx,y\n" + "\n".join(f"{x:.3f} {y:.3f}" for x, y in stadium())
    (folder / "track.csv").write_text(text)
    monkeypatch.setenv("PILOTLAB_CIRCUITS", str(folder))
    monkeypatch.chdir(tmp_path)
    circuit = get_circuit("track")
    assert circuit.name == "track" and circuit.length == pytest.approx(stadium_length(), rel=0.01)
    assert circuit.timeout_s == pytest.approx(circuit.length / 5.0)
    from pilotlab.circuits import all_circuit_names
    assert all_circuit_names()[-1] == "track"


def test_a_bad_csv_says_where(tmp_path):
    path = write_csv(tmp_path / "bad.csv", stadium()[:20])
    path.write_text(path.read_text() + "1.0,oops\n")
    with pytest.raises(PilotlabError, match=r"bad.csv:22: expected 'x,y'"):
        read_points_csv(path)
    with pytest.raises(PilotlabError, match="at least 3"):
        read_points_csv(write_csv(tmp_path / "short.csv", stadium()[:2]))


def test_a_one_column_csv_is_refused_at_its_first_value_not_read_as_headers(tmp_path):
    """Outside test: `x` then `1`, `2`, `3` said "needs at least 3 'x,y' lines, found 0" (every line was taken
    for a header)."""
    path = tmp_path / "one.csv"
    path.write_text("x\n1\n2\n3\n")
    with pytest.raises(PilotlabError, match=r"one.csv:2: expected 'x,y' in metres, got '1'"):
        read_points_csv(path)
