from __future__ import annotations

import pytest
import torch

from matrix.errors import UnknownNameError
from matrix.kinds import NotApplicable
from pilotlab.errors import PilotlabError
from pilotlab.hardware import (apply_profile, check_available, cpu_count, describe_host, host_fingerprint,
                               make_profile, profile_from_dict)


def test_builtin_profiles():
    assert make_profile("cpu").threads is None and make_profile("cpu").cpu_threads == cpu_count()
    assert make_profile("cpu1").cpu_threads == 1
    assert make_profile("cuda").device == "cuda"


def test_recipe_profile_and_round_trip_through_job_params():
    profile = make_profile("two", {"device": "cpu", "threads": 2})
    assert profile_from_dict(profile.as_dict()) == profile
    assert profile_from_dict({"name": "cpu1"}) == make_profile("cpu1")


@pytest.mark.parametrize("options, message", [({"device": "tpu"}, "device"), ({"threads": 0}, "threads"),
                                              ({"cores": 2}, "unknown option")])
def test_bad_recipe_profiles_say_what_is_wrong(options, message):
    with pytest.raises(PilotlabError, match=message):
        make_profile("mine", options)


def test_unknown_builtin_suggests_one():
    with pytest.raises(UnknownNameError, match="did you mean 'cpu'"):
        make_profile("cpu2")


@pytest.mark.skipif(torch.cuda.is_available(), reason="this host has a GPU")
def test_cuda_is_not_applicable_without_a_gpu():
    with pytest.raises(NotApplicable, match="needs a CUDA GPU"):
        check_available(make_profile("cuda"))


def test_more_threads_than_cores_is_not_applicable():
    with pytest.raises(NotApplicable, match="cores"):
        check_available(make_profile("big", {"threads": cpu_count() + 1}))


def test_applying_a_profile_sets_torch_threads():
    before = torch.get_num_threads()
    try:
        apply_profile(make_profile("cpu1"))
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)


def test_host_fingerprint():
    host = host_fingerprint()
    assert set(host) == {"cpu", "cores", "machine", "gpu"} and host["cores"] >= 1 and host["cpu"]
    assert str(host["cores"]) in describe_host(host)


def test_the_gpu_name_is_torchs_wherever_a_gpu_driver_is_present(monkeypatch):
    from pilotlab import hardware
    expected = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    for device_files in (hardware.GPU_DEVICE_FILES, ("/dev/null",)):   # this host's, and "a driver here"
        monkeypatch.setattr(hardware, "GPU_DEVICE_FILES", device_files)
        hardware.gpu_name.cache_clear()
        assert hardware.gpu_name() == expected
    hardware.gpu_name.cache_clear()


def test_work_that_is_not_timed_keeps_to_its_workers_share_of_the_cores(monkeypatch):
    from pilotlab.hardware import BUILTIN, cpu_count, within_share, worker_share
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert worker_share() == 1 and within_share(BUILTIN["cpu"]).threads == 1
    assert within_share(BUILTIN["cuda"]) == BUILTIN["cuda"]
    monkeypatch.delenv("OMP_NUM_THREADS")
    assert worker_share() == cpu_count() and within_share(BUILTIN["cpu1"]).threads == 1


def test_a_profile_can_name_the_dask_worker_resource_of_its_machine():
    jetson = make_profile("jetson", {"threads": 4, "worker_resource": "JETSON"})
    assert jetson.worker_resource == "JETSON" and profile_from_dict(jetson.as_dict()) == jetson
    assert jetson.host is None   # timed on the machine the resource names, whichever host plans it
    # a profile without one carries the params it always did (the keys of earlier timings stay)
    assert make_profile("two", {"threads": 2}).as_dict() == {"name": "two", "device": "cpu", "threads": 2}
    with pytest.raises(PilotlabError, match="hardware.jetson.worker_resource"):
        make_profile("jetson", {"worker_resource": "JETSON=1"})
