"""The replay timing mode: a lap charged latencies measured once gives the same trajectory and metrics
on a quiet machine and beside two CPU hogs; latency samples from the timing job and from a user's file."""
import subprocess
import sys

import numpy as np
import pytest

from pilotlab.errors import PilotlabError
from pilotlab.online.bm_metrics import bm_run_metrics
from pilotlab.online.brains import NetworkBrain
from pilotlab.online.drive import DriveSettings, drive
from pilotlab.online.latency import latency_file_samples, timing_samples
from pilotlab.online.metrics import run_metrics
from pilotlab.online.trajectory import COLUMNS
from pilotlab.predictor import load_predictor
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv

WALL_CLOCK = {"wall"}                                   # the host's clock: the only column allowed to differ
WALL_METRICS = {"real_time_factor"}


def network_lap(artifact, samples):
    brain = NetworkBrain(load_predictor(artifact, "cpu1"))
    brain.warm_up()
    with DrivingEnv("simple_circuit", camera=CameraSpec(), renderer="ground", timeout_s=4.0) as env:
        return drive(env, brain, DriveSettings(timing="replay"), seed=3, latency_ms=samples)


def test_a_replayed_lap_is_the_same_beside_two_cpu_hogs(pilotnet_artifact):
    samples = np.array([4.0, 18.0, 45.0, 90.0])
    quiet = network_lap(pilotnet_artifact, samples)
    hogs = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(2)]
    try:
        loaded = network_lap(pilotnet_artifact, samples)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    assert len(quiet.decisions) > 20
    for column in set(COLUMNS) - WALL_CLOCK:
        np.testing.assert_array_equal(getattr(quiet, column), getattr(loaded, column), err_msg=column)
    checkpoints = np.stack([quiet.x, quiet.y], axis=1)
    for metrics in (run_metrics, lambda t: bm_run_metrics(t, checkpoints)):
        first, second = metrics(quiet), metrics(loaded)
        assert {k: v for k, v in first.items() if k not in WALL_METRICS} == \
               {k: v for k, v in second.items() if k not in WALL_METRICS}


def test_timing_samples_follow_the_timing_jobs_contract(tmp_path):
    np.save(tmp_path / "latency_ms.npy", np.array([2.5, 3.0, 2.75]))
    np.testing.assert_array_equal(timing_samples(tmp_path, {"latency_samples": "latency_ms.npy"}), [2.5, 3.0, 2.75])
    with pytest.raises(PilotlabError, match="kept no latency samples.*pilotlab run --force timing"):
        timing_samples(tmp_path, {})
    with pytest.raises(PilotlabError, match="latency samples are missing; rerun it with `pilotlab run --force timing`"):
        timing_samples(tmp_path, {"latency_samples": "gone.npy"})


def test_a_latency_file_gives_the_most_specific_rows(tmp_path):
    path = tmp_path / "jetson.csv"
    path.write_text("# measured on a Jetson Nano\nmodel,strategy,latency_ms\npilotnet,baseline,124\npilotnet,baseline,126\n"
                    "pilotnet,,40\n,dynamic_quant,60\n,,99\n")
    assert list(latency_file_samples(path, "pilotnet", "baseline")) == [124.0, 126.0]
    assert list(latency_file_samples(path, "pilotnet", "qat")) == [40.0]
    assert list(latency_file_samples(path, "other", "dynamic_quant")) == [60.0]
    assert list(latency_file_samples(path, "other", "qat")) == [99.0]
    path.write_text("latency_ms\n5\n6\n")
    assert list(latency_file_samples(path, "any", "any")) == [5.0, 6.0]
    path.write_text("strategy,ms\nbaseline,5\n")
    with pytest.raises(PilotlabError, match="latency_ms column"):
        latency_file_samples(path, "pilotnet", "baseline")


def test_scaling_gives_the_reference_its_target_median():
    from pilotlab.online.latency import scale_to
    scaled, factor, stalls = scale_to(np.array([1.0, 1.5]), np.array([2.0, 2.0, 3.0]), 124.0)
    assert factor == pytest.approx(62.0) and list(scaled) == pytest.approx([62.0, 93.0]) and stalls == 0


def test_a_host_stall_is_not_scaled_into_a_freeze():
    """A call the host stalled (8.6 ms among ~0.95 ms ones) adds its own delay on the slower device, not
    ×127 of it: scaled whole it would stop the car for a second."""
    from pilotlab.online.latency import scale_to
    samples = np.array([0.9, 1.0, 1.0, 1.0, 1.1, 2.9, 8.6])                          # median 1.0
    scaled, factor, stalls = scale_to(samples, np.array([1.0]), 124.0)
    assert factor == 124.0 and stalls == 1
    assert list(scaled[:6]) == pytest.approx([111.6, 124.0, 124.0, 124.0, 136.4, 359.6])   # 2.9 < 3× median: work
    assert scaled[6] == pytest.approx(124.0 + 7.6)                                     # median's work + the stall


def test_a_timing_source_takes_the_file_over_the_timing_job_and_scales(tmp_path):
    from pilotlab.online.latency import TimingSource
    np.save(tmp_path / "latency_ms.npy", np.array([2.0, 2.0, 4.0]))
    np.save(tmp_path / "base.npy", np.array([4.0]))
    timing = (tmp_path, {"latency_samples": "latency_ms.npy"})
    samples, said = TimingSource(timing=timing).samples()
    assert list(samples) == [2.0, 2.0, 4.0] and said["latency_source"] == "timing job"
    assert said["replayed_latency_ms"] == 2.0 and "latency_scale" not in said
    scaled, said = TimingSource(timing=timing, scale_to_ms=124.0, reference=(tmp_path, {"latency_samples": "base.npy"})
                                ).samples()
    assert list(scaled) == [62.0, 62.0, 124.0] and said["latency_scale"] == 31.0 and said["replayed_stalls"] == 0
    path = tmp_path / "device.csv"
    path.write_text("strategy,latency_ms\nbaseline,30\nqat,10\n")
    samples, said = TimingSource(timing=timing, latency_file=path, strategy="qat").samples()
    assert list(samples) == [10.0] and said["latency_source"] == "latency file device.csv"
    with pytest.raises(PilotlabError, match="needs the timing job"):
        TimingSource().samples()


def test_drive_takes_an_artifact_s_rows_of_a_latency_file_by_its_arch(pilotnet_artifact, tmp_path):
    """Outside test: `drive --latency-file` looked rows up with no model, so the docs' own example rows
    (`pilotnet,baseline,31.2`) never matched, and its result.json lacked latency_source."""
    import json

    from pilotlab.cli import main
    timings = tmp_path / "device.csv"
    timings.write_text("model,strategy,latency_ms\npilotnet,baseline,31.2\nother,baseline,500\n,,900\n")
    out = tmp_path / "run"
    assert main(["drive", "--artifact", str(pilotnet_artifact), "--circuit", "simple_circuit", "--timeout", "2",
                 "--latency-file", str(timings), "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["replayed_latency_ms"] == 31.2 and result["latency_source"] == "latency file device.csv"
