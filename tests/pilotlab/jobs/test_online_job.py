"""The `online` job kind through its registered handler, with hand-made JobContexts as the engine makes
them: an optimized artifact's brain, the reference brains, the files, and the report row it feeds."""
import json
import re

import numpy as np

import pytest

import pilotlab.jobs.online  # noqa: F401  (registers the kind)
from matrix.kinds import KINDS, DepResult, NotApplicable
from pilotlab.columns import BEHAVIORMETRICS, ONLINE
from pilotlab.errors import PilotlabError
from pilotlab.hardware import host_fingerprint
from pilotlab.online.trajectory import load_npz
from pilotlab.report import ReportRow, pick_metrics
from tests.pilotlab.jobs.context import context
from tests.pilotlab.online.conftest import baseline_artifact

SHORT = {"circuit": "simple_circuit", "timeout_s": 2.0, "hardware": {"name": "cpu1", "threads": 1},
         "camera_frames": 0}


@pytest.fixture(scope="module")
def artifact_dep(tmp_path_factory, trained) -> DepResult:
    folder = baseline_artifact(trained / "model.pt", tmp_path_factory.mktemp("artifact"))
    return DepResult(key="optimize-key", kind="optimize", params={"strategy": "baseline"},
                     result={"strategy": "baseline"}, artifacts=folder, name="optimize:baseline")


def run(tmp_path, name, params, deps=None):
    ctx = context(tmp_path, "online", name, params, deps=deps)
    return ctx, KINDS.get("online").handler(ctx)


def test_an_artifact_drives_from_two_start_points(tmp_path, artifact_dep):
    progress = []
    ctx = context(tmp_path, "online", "online-net", {**SHORT, "repetitions": 2, "host": host_fingerprint(),
                                                    "fixed_inference_ms": 5.0},
                  deps={"artifact": artifact_dep}, progress=lambda **kw: progress.append(kw))
    result = KINDS.get("online").handler(ctx)
    json.dumps(result)
    assert result["strategy"] == "baseline" and result["brain"] == "baseline" and result["repetitions"] == 2
    assert result["hardware"] == {"name": "cpu1", "device": "cpu", "threads": 1} and result["timing"] == "replay"
    starts = [run["start_m"] for run in result["runs"]]
    assert starts[0] == 0.0 and starts[1] == pytest.approx(result["circuit_length_m"] / 2, abs=1e-3)
    measured = set(pick_metrics(result))
    assert {"completed_distance_m", "position_deviation_mae_m", "brain_frequency_sim_hz", "mean_inference_ms",
            "real_time_factor", "off_road_events", "bm_percentage_completed", "bm_position_deviation_mae",
            "bm_suddenness"} <= measured <= {c.name for c in ONLINE + BEHAVIORMETRICS}
    assert result["mean_inference_ms"] == pytest.approx(5.0) and result["measured_inference_ms"] > 0
    assert result["spread"]["completed_distance_m"]["runs"] == 2
    assert (ctx.out / result["trajectory"]).stat().st_size > 10_000
    runs = load_npz(ctx.out / result["trajectory_data"])
    assert [len(r.decisions) for r in runs] == [run["iterations"] for run in result["runs"]]
    assert (ctx.out / result["trajectory_csv"]).read_text().startswith("run,t,wall")
    assert "run 2/2" in progress[-1]["description"]
    row = ReportRow.model_validate({"model": "pilotnet", "strategy": result["strategy"], "hardware": "cpu1",
                                    "kind": "online", "circuit": result["circuit"], **pick_metrics(result),
                                    "trajectory": ctx.out / result["trajectory"]})
    assert row.get("mean_inference_ms") == pytest.approx(5.0)


def test_a_network_lap_replays_the_timing_jobs_latency_scaled_and_searches_its_tolerance(tmp_path, artifact_dep):
    timed = tmp_path / "timing"
    timed.mkdir()
    np.save(timed / "latency_ms.npy", np.array([3.0, 4.0, 5.0]))
    np.save(timed / "base.npy", np.array([2.0]))
    timing = DepResult(key="timing-key", kind="timing", params={}, result={"latency_samples": "latency_ms.npy"},
                       artifacts=timed, name="timing:baseline")
    base = DepResult(key="timing-base", kind="timing", params={}, result={"latency_samples": "base.npy"},
                     artifacts=timed, name="timing:baseline")
    _, result = run(tmp_path, "online-replay", {**SHORT, "latency_scale_to_ms": 20.0,
                                                "tolerance": {"fixed_ms": [0, 50], "max_ms": 100, "step_ms": 25}},
                    deps={"artifact": artifact_dep, "timing": timing, "scale_reference": base})
    assert result["latency_source"] == "timing job, scaled ×10 so that baseline takes 20 ms"
    assert result["latency_scale"] == 10.0 and result["replayed_latency_ms"] == 40.0
    assert result["bm_mean_inference_ms"] is None or 30.0 <= result["bm_mean_inference_ms"] <= 50.0
    assert {lap["injected_ms"] for lap in result["tolerance_laps"]} >= {0.0}
    kept = result["tolerance_laps"][0]["lap_completed"]     # lost at 0 ms, no other lap is driven
    assert "latency_tolerance_ms" in result and result["tolerance_fixed_ms"] == ([0.0, 50.0] if kept else [0.0])
    assert "tolerance_hint_ms" not in result


def test_a_lap_starts_its_tolerance_search_at_its_neighbours_tolerance(tmp_path):
    neighbour = DepResult(key="lap-key", kind="online", params={}, result={"latency_tolerance_ms": 75.0},
                          artifacts=tmp_path, name="online expert on cpu1 at simple_circuit cw")
    params = {**SHORT, "timeout_s": None, "laps": 0.2, "brain": "expert", "fixed_inference_ms": 0.0,
              "tolerance": {"fixed_ms": [0, 25], "max_ms": 100, "step_ms": 25}}
    _, result = run(tmp_path, "online-hinted", params, deps={"tolerance_hint": neighbour})
    assert result["tolerance_hint_ms"] == 75.0 and result["tolerance_hint_from"] == neighbour.name
    outcomes = {lap["injected_ms"]: lap["lap_completed"] for lap in result["tolerance_laps"]}
    assert outcomes[0.0] and 75.0 in outcomes and 25.0 not in outcomes   # the hint first, no fixed lap
    assert result["tolerance_fixed_ms"] == [0.0]


def test_reference_brains_with_video_and_stills(tmp_path):
    _, expert = run(tmp_path, "online-expert", {**SHORT, "brain": "expert", "starts": [100.0, 300.0]})
    assert expert["strategy"] == "expert" and expert["repetitions"] == 2 and expert["lap_completed"] is False
    assert [r["start_m"] for r in expert["runs"]] == [100.0, 300.0] and "video" not in expert
    ctx, explicit = run(tmp_path, "online-explicit", {**SHORT, "brain": "explicit", "video": True,
                                                     "video_seconds": 1.0, "camera_frames": 2,
                                                     "camera": {"width": 320, "height": 240}})
    assert explicit["position_deviation_mae_m"] < 0.5 and explicit["off_road_events"] == 0
    assert (ctx.out / explicit["video"]).stat().st_size > 0 and len(explicit["camera_frames"]) == 2
    for result in (expert, explicit):   # replayed, charged no inference time: none reported (it read 0 ms)
        assert result["latency_source"].startswith("none:") and result["mean_inference_ms"] is None
        assert all(run["mean_inference_ms"] is None for run in result["runs"]) and result["measured_inference_ms"] > 0


def test_a_cuda_profile_on_a_host_without_a_gpu_is_not_applicable(tmp_path):
    import torch
    if torch.cuda.is_available():
        pytest.skip("this host has a GPU")
    with pytest.raises(NotApplicable, match="needs a CUDA GPU"):
        run(tmp_path, "online-cuda", {**SHORT, "brain": "explicit", "hardware": {"name": "cuda", "device": "cuda"}})


def test_the_kind_runs_alone_on_the_hosts_clock_only_and_asks_for_a_gpu_only_for_cuda():
    kind = KINDS.get("online")
    assert [kind.runs_alone({"timing": timing}) for timing in ("measured", "realtime", "replay", "lockstep")] == [
        True, True, False, False]
    assert not kind.runs_alone({})   # replay, the default
    assert kind.resources_for({"hardware": {"name": "cuda", "device": "cuda"}}) == {"GPU": 1}
    assert kind.resources_for({"hardware": {"name": "cpu1", "device": "cpu", "threads": 1}}) == {}
    names = set(kind.base_modules())
    assert {"pilotlab.online.metrics", "pilotlab.online.drive", "pilotlab.sim.env", "pilotlab.predictor",
            "pilotlab.hardware", "pilotlab.specs.online"} <= names


@pytest.mark.parametrize("params, deps, message", [
    ({"circuit": "simple_circuit", "brain": "expert", "timout_s": 3}, False, "online-bad: unknown param 'timout_s' .did you mean 'timeout_s'.."),
    ({"brain": "expert"}, False, "circuit: Field required"),
    ({"circuit": "simple_circuit"}, False, "an 'artifact' dependency .an optimize job. or brain: one of explicit"),
    ({"circuit": "simple_circuit", "brain": "explicit"}, True, "has an artifact dependency and brain='explicit'"),
    ({"circuit": "simple_circuit", "brain": "expert", "starts": [0.0, 10.0], "repetitions": 3}, False,
     "starts lists 2 point.s. but repetitions is 3"),
    ({"circuit": "simple_circuit", "brain": "expert", "timing": "lockstep", "fixed_inference_ms": 3}, False,
     "only means something in the replay and measured timing modes"),
    ({"circuit": "simple_circuit", "timeout_s": 1.0}, True, "needs the timing job"),
    ({"circuit": "simple_circut", "brain": "expert"}, False, "did you mean 'simple_circuit'"),
])
def test_params_are_checked(tmp_path, artifact_dep, params, deps, message):
    with pytest.raises(PilotlabError, match=message):
        run(tmp_path, "online-bad", params, deps={"artifact": artifact_dep} if deps else None)


def test_a_lap_on_this_host_s_clock_beside_other_processes_is_marked_unstable():
    """Outside test: a measured lap beside two CPU hogs read 712 ms of inference (2 ms quiet), the car
    crawled, and nothing said so. The lap now says how many cores others took; the report marks it ⚠."""
    from dataclasses import replace
    from pilotlab import timing
    from pilotlab.hardware import profile_from_dict
    from pilotlab.jobs.online import disturbed_lap
    profile = profile_from_dict({"name": "cpu", "threads": 1})
    now = timing.snapshot()
    if now.busy is None:
        pytest.skip("no /proc/stat here")
    cores = len(timing.our_cpus())
    busy = replace(now, wall=now.wall - 1.0, process=now.process - 1.0, busy=now.busy - 1.0 - cores)
    reason = disturbed_lap(busy, profile, "measured")
    # a measured figure: the real machine's own load between the two snapshots adds to the faked one
    # (`.ci/run`'s slow stream beside it read 2.02 of 2)
    used = re.match(r"other processes used ([\d.]+) of \d+ cores during this lap", reason)
    assert used and abs(float(used.group(1)) - cores) < 0.5 and "beside the 1 its measured timing needs" in reason
    assert ReportRow(model="m", strategy="s", hardware="cpu", kind="online", unstable={"latency_ms": reason}) \
        .unstable_reason("latency_ms") == reason
    quiet = replace(now, wall=now.wall - 1.0, process=now.process - 1.0, busy=now.busy - 1.0)
    assert disturbed_lap(quiet, profile, "measured") is None
