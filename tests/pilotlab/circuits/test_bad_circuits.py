"""Circuit CSVs that are not a drivable lap are refused with the file and the reason, at once."""
import os
import time

import numpy as np
import pytest

from pilotlab.circuits.load import get_circuit
from pilotlab.errors import PilotlabError
from tests.pilotlab.tracks import stadium, write_csv


def figure_eight(radius: float = 15.0, start: float = np.pi / 2, endpoint: bool = False) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, 400, endpoint=endpoint) + start   # by default, starts away from the crossing
    return np.stack([radius * np.sin(2 * t), radius * np.sin(t)], axis=1)


def with_point(points: np.ndarray, index: int, value) -> np.ndarray:
    points = points.copy()
    points[index] = value
    return points


BAD = {
    "nan point": (lambda: with_point(stadium(), 40, (np.nan, 1.0)), r"bad.csv:42: the point \(nan, 1.0000\) is not a finite"),
    "inf point": (lambda: with_point(stadium(), 5, (np.inf, 1.0)), r"bad.csv:7: the point \(inf, 1.0000\)"),
    "1e300 point": (lambda: with_point(stadium(), 5, (1e300, 1.0)), r"bad.csv:7: the point .* within 1e\+06 m"),
    "1e12-scaled": (lambda: stadium() * 1e12, r"bad.csv:2: the point .* within 1e\+06 m"),
    "1e4-scaled": (lambda: stadium() * 1e4, r"m long, more than 100000 m; are the coordinates in metres\?"),
    "collinear": (lambda: np.stack([np.r_[np.linspace(0, 100, 200), np.linspace(100, 0, 200)], np.zeros(400)], axis=1),
                  "encloses almost no area"),
    "open line": (lambda: np.stack([np.linspace(0, 100, 200), np.zeros(200)], axis=1), "is not a lap: it ends 100.0 m"),
    "out and back": (lambda: np.concatenate([np.stack([np.linspace(0, 100, 200), np.zeros(200)], axis=1),
                                             np.stack([np.linspace(100, 0, 200), np.full(200, 0.5)], axis=1)]),
                     "encloses almost no area"),
    "figure eight": (figure_eight, r"crosses itself near x=-?0\.\d, y=-?0\.\d m"),
    # started at its crossing, it passes its start half-way: that is the crossing, not where the lap closes
    "figure eight from its crossing": (lambda: figure_eight(start=0.0), r"crosses itself near x=-?0\.\d, y=-?0\.\d m"),
    "figure eight from its crossing, closed": (lambda: figure_eight(60.0, start=0.0, endpoint=True),
                                               r"crosses itself near x=-?0\.\d, y=-?0\.\d m"),
    "open zig-zag": (lambda: np.array([(10.0 * i, 10.0 * (i % 2)) for i in range(12)]), "is not a lap: it ends 110.5 m from its start"),
    # outside test: a 2 m circle "encloses almost no area", true but not the point
    "tiny circle": (lambda: circle(2.0), r"too small for its \d+ m road: the lap spans 3.0 m once smoothed"),
}


def circle(radius: float) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    return np.stack([radius * np.cos(t), radius * np.sin(t)], axis=1)


@pytest.mark.parametrize("case", BAD)
def test_a_bad_circuit_is_refused_with_its_reason(tmp_path, case):
    make, message = BAD[case]
    csv = write_csv(tmp_path / "bad.csv", make())
    started = time.monotonic()
    with pytest.raises(PilotlabError, match=message) as caught:
        get_circuit(str(csv))
    assert "\n" not in str(caught.value) and str(csv) in str(caught.value)
    assert time.monotonic() - started < 5


def test_a_binary_csv_names_the_line(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_bytes(b"x,y\n0,0\n1,0\n" + os.urandom(64).replace(b"\n", b"") + b"\xff\n")
    with pytest.raises(PilotlabError, match=r"bad.csv:4: not a text file \(byte 0x.. is not UTF-8\)"):
        get_circuit(str(path))


def test_good_circuits_still_pass(tmp_path):
    assert get_circuit("montreal").length > 1000
    # outside test: a polygon's corners, its first not repeated, were "not a lap" (the closing side not assumed)
    square = get_circuit(str(write_csv(tmp_path / "square.csv", np.array([(0, 0), (100, 0), (100, 100), (0, 100.0)]))))
    assert 390 < square.length < 400
    stadium_circuit = get_circuit(str(write_csv(tmp_path / "stadium.csv", stadium())))
    assert stadium_circuit.length > 100
