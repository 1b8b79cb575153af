"""The latency tolerance search: on a lap function whose answer is known, and in the simulator."""
import time

import pydantic
import pytest

from pilotlab.online.brains import make_reference_brain
from pilotlab.online.drive import drive
from pilotlab.online.evaluate import evaluate_online
from pilotlab.online.perfect_lap import perfect_lap
from pilotlab.online.tolerance import LapOutcome, tolerance_search
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv
from pilotlab.specs.online import DriveSettings, OnlineSpec, ToleranceSpec
from tests.pilotlab.tracks import stadium, write_csv


class Threshold:
    """Completes the lap up to `limit` ms injected; counts the laps driven."""

    def __init__(self, limit):
        self.limit, self.driven = limit, []

    def __call__(self, ms):
        self.driven.append(ms)
        return LapOutcome(ms, ms <= self.limit, {"position_deviation_mae_m": 0.1 + ms / 1000})


@pytest.mark.parametrize("limit, expected, at_least", [(137.0, 130.0, False), (60.0, 60.0, False), (0.0, 0.0, False),
                                                       (-1.0, None, False), (2000.0, 1000.0, True),
                                                       (997.0, 990.0, False)])
def test_the_search_finds_the_largest_completed_latency_on_the_grid(limit, expected, at_least):
    lap = Threshold(limit)
    found = tolerance_search(lap, ToleranceSpec())
    assert found["latency_tolerance_ms"] == expected and found["tolerance_at_least"] is at_least
    assert len(set(lap.driven)) == len(lap.driven) <= 3 + 7      # fixed latencies, then bisection to 10 ms
    assert [lap["injected_ms"] for lap in found["tolerance_laps"]] == sorted(lap.driven)


def test_probing_high_in_the_bracket_finds_the_same_tolerance_with_fewer_completed_laps():
    """A completed lap is a whole (slower) lap, a lost one ends early: probing 0.7 of the way up the
    bracket completes fewer laps than bisecting, and finds the same tolerances."""
    completed = {}
    for probe in (0.5, 0.7):
        laps, found = [], []
        for limit in range(0, 1000, 7):
            lap = Threshold(float(limit))
            found.append(tolerance_search(lap, ToleranceSpec(probe=probe))["latency_tolerance_ms"])
            laps += [ms for ms in lap.driven if ms <= limit]
        completed[probe] = (len(laps), found)
    assert completed[0.7][1] == completed[0.5][1]
    assert completed[0.7][0] < completed[0.5][0]


@pytest.mark.parametrize("off_by", [-300.0, -30.0, -20.0, -10.0, 0.0, 10.0, 20.0, 30.0, 300.0])
def test_a_hint_finds_the_same_tolerance_and_a_good_one_in_fewer_laps(off_by):
    """Started at a neighbour cell's tolerance, the search finds what it finds without (a hint only
    orders the laps), at any distance from the truth; within a step, in two laps after the 0 ms one."""
    for limit in [-1.0, *range(0, 1100, 7)]:
        plain = Threshold(float(limit))
        expected = tolerance_search(plain, ToleranceSpec())
        hint = max(0.0, (expected["latency_tolerance_ms"] or 0.0) + off_by)
        lap = Threshold(float(limit))
        found = tolerance_search(lap, ToleranceSpec(), hint_ms=hint)
        assert (found["latency_tolerance_ms"], found["tolerance_at_least"]) == \
               (expected["latency_tolerance_ms"], expected["tolerance_at_least"])
        assert len(set(lap.driven)) == len(lap.driven)
        if off_by == 0.0 and 0 <= limit < 1000:
            assert len(lap.driven) <= 1 + 2 and len(lap.driven) < len(plain.driven)


def test_a_hinted_search_drives_no_fixed_latency_below_its_tolerance():
    """Each such lap is a whole (slow) lap that decides nothing the hint's laps do not."""
    lap = Threshold(137.0)
    found = tolerance_search(lap, ToleranceSpec(), hint_ms=130.0)
    assert found["latency_tolerance_ms"] == 130.0 and lap.driven == [0.0, 130.0, 140.0]
    assert found["tolerance_fixed_ms"] == [0.0]
    assert tolerance_search(Threshold(137.0), ToleranceSpec())["tolerance_fixed_ms"] == [0.0, 100.0, 200.0]


def test_a_hint_above_the_fixed_latencies_needs_no_lap_at_max_ms():
    """The explicit brain keeps its lap at +200 ms: the bisection drove the max_ms lap and six more;
    from a neighbour's 200 ms, one lap (lost at 210) decides."""
    lap = Threshold(205.0)
    found = tolerance_search(lap, ToleranceSpec(), hint_ms=200.0)
    assert found["latency_tolerance_ms"] == 200.0 and lap.driven == [0.0, 200.0, 210.0]


def test_known_laps_are_not_driven_again():
    lap = Threshold(137.0)
    found = tolerance_search(lap, known={0.0: LapOutcome(0.0, True)})
    assert 0.0 not in lap.driven and found["tolerance_laps_driven"] == len(lap.driven)
    assert found["tolerance_laps"][0]["injected_ms"] == 0.0


def test_fixed_latencies_must_lie_on_the_grid():
    with pytest.raises(pydantic.ValidationError, match="multiples of step_ms"):
        ToleranceSpec(fixed_ms=[0.0, 33.0])


def test_a_vanishing_step_is_refused_not_a_traceback():
    """Found by the slow fuzz: step_ms 1e-300 overflowed the grid check (OverflowError)."""
    with pytest.raises(pydantic.ValidationError, match="greater than or equal to 0.1"):
        ToleranceSpec(step_ms=1e-300)


@pytest.fixture(scope="module")
def track(tmp_path_factory):
    return str(write_csv(tmp_path_factory.mktemp("tolerance") / "stadium.csv", stadium(30.0, 12.0)))


def expert_cell(track, out, tolerance=None, brain="expert", checkpoints=None):
    spec = OnlineSpec(circuit=track, timeout_s=40.0, timing="replay", fixed_inference_ms=0.0)
    return evaluate_online(make_reference_brain(brain), spec, out, tolerance=tolerance, checkpoints=checkpoints)


def test_the_expert_tolerates_latency_up_to_a_limit_it_finds(track, tmp_path):
    found = expert_cell(track, tmp_path, ToleranceSpec(fixed_ms=[0.0, 100.0, 300.0], max_ms=600.0, step_ms=10.0))
    tolerance = found["latency_tolerance_ms"]
    laps = {lap["injected_ms"]: lap for lap in found["tolerance_laps"]}
    assert found["lap_completed"] and tolerance is not None and 0 < tolerance < 600
    assert laps[tolerance]["lap_completed"] and not laps[tolerance + 10]["lap_completed"]
    assert laps[0.0]["position_deviation_mae_m"] == found["position_deviation_mae_m"]   # the plain lap, shared
    assert laps[0.0]["bm_position_deviation_mae"] == found["bm_position_deviation_mae"]  # with its scores
    assert laps[100.0]["bm_position_deviation_mae"] is not None                         # a fixed latency's
    assert not laps[tolerance + 10]["termination"] == "lap_completed"


@pytest.mark.benchmark
@pytest.mark.parametrize("brain", ["expert", "explicit"])
def test_benchmark_tolerance_search_against_one_plain_lap(track, tmp_path, brain):
    camera = CameraSpec() if brain == "explicit" else None
    with DrivingEnv(track, camera=camera, renderer="ground", timeout_s=40.0) as env:
        started = time.perf_counter()
        drive(env, make_reference_brain(brain), DriveSettings(fixed_inference_ms=0.0))
        lap_s = time.perf_counter() - started
    checkpoints = perfect_lap(track)
    started = time.perf_counter()
    plain = expert_cell(track, tmp_path / "plain", brain=brain, checkpoints=checkpoints)
    plain_s = time.perf_counter() - started
    started = time.perf_counter()
    found = expert_cell(track, tmp_path / "search", ToleranceSpec(), brain=brain, checkpoints=checkpoints)
    search_s = time.perf_counter() - started - plain_s
    print(f"\n{brain} on a {plain['circuit_length_m']:.0f} m stadium: one plain lap {lap_s:.2f} s, its online "
          f"evaluation {plain_s:.2f} s (metrics, files); the tolerance search adds {search_s:.2f} s = "
          f"{search_s / lap_s:.1f} plain laps for {found['tolerance_laps_driven']} laps driven (lost ones stop "
          f"early); tolerance {found['latency_tolerance_ms']} ms")
