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


def test_the_gpu_name_comes_from_the_nvidia_driver_without_torch_when_unambiguous(tmp_path, monkeypatch):
    """`plan` fingerprints the host: on a GPU host torch's import and CUDA start-up cost seconds."""
    from pilotlab import hardware
    for bus, model in (("0000:01:00.0", "NVIDIA H100 80GB HBM3"), ("0000:02:00.0", "NVIDIA H100 80GB HBM3")):
        (tmp_path / "gpus" / bus).mkdir(parents=True)
        (tmp_path / "gpus" / bus / "information").write_text(f"Model: \t\t {model}\nIRQ:   42\nBus Type:  PCIe\n")
    monkeypatch.setattr(hardware, "GPU_DEVICE_FILES", ("/dev/null",))
    monkeypatch.setattr(hardware, "NVIDIA_GPU_INFO", str(tmp_path / "gpus" / "*" / "information"))
    monkeypatch.setattr(hardware, "NVIDIA_MIG_INSTANCES", str(tmp_path / "capabilities" / "gpu*" / "mig" / "gi*"))
    monkeypatch.setattr(hardware, "_torch_cuda_build", lambda: True)
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
    monkeypatch.delenv("NVIDIA_VISIBLE_DEVICES", raising=False)
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda *args: "asked torch")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)

    def name() -> str | None:
        hardware.gpu_name.cache_clear()
        return hardware.gpu_name()
    try:
        assert name() == "NVIDIA H100 80GB HBM3"
        monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "1")            # which GPU is device 0: torch knows
        assert name() == "asked torch"
        monkeypatch.delenv("CUDA_VISIBLE_DEVICES")
        monkeypatch.setenv("NVIDIA_VISIBLE_DEVICES", "MIG-4f2c")   # a container given one MIG slice
        assert name() == "asked torch"
        monkeypatch.delenv("NVIDIA_VISIBLE_DEVICES")
        (tmp_path / "capabilities" / "gpu0" / "mig" / "gi1").mkdir(parents=True)   # torch names the slice
        assert name() == "asked torch"
        (tmp_path / "capabilities" / "gpu0" / "mig" / "gi1").rmdir()
        (tmp_path / "gpus" / "0000:02:00.0" / "information").write_text("Model: NVIDIA A100-SXM4-40GB\n")
        assert name() == "asked torch"                                  # two models
        monkeypatch.setattr(hardware, "_torch_cuda_build", lambda: False)
        assert name() is None                                           # a CPU-only torch uses no GPU
    finally:
        hardware.gpu_name.cache_clear()


def test_a_cpu_only_torch_is_told_from_its_version_file():
    from pilotlab import hardware
    assert hardware._torch_cuda_build() is (torch.version.cuda is not None)


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


def test_a_profile_of_another_machine_is_timed_only_on_the_dask_worker_that_has_its_resource():
    """Outside test: a local run timed a `worker_resource: JETSON` profile on the laptop and stored the
    figures under the profile's key as the Jetson's (a later run on the cluster found them fresh)."""
    from pilotlab.hardware import HardwareProfile, check_on_its_machine
    jetson = HardwareProfile("jetson", threads=1, worker_resource="JETSON")
    check_on_its_machine(HardwareProfile("cpu1", threads=1), "timing x")     # a profile of this host: anywhere
    with pytest.raises(PilotlabError, match=r"timing x: hardware 'jetson' stands for the machine of the Dask worker "
                                            r"resource 'JETSON', and this job times it outside Dask .*--resources JETSON=1"):
        check_on_its_machine(jetson, "timing x")
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
                                  resources={"JETSON": 1}) as cluster, distributed.Client(cluster) as client:
        assert client.submit(check_on_its_machine, jetson, "timing x", resources={"JETSON": 1}).result() is None
        other = HardwareProfile("nano", threads=1, worker_resource="NANO")
        with pytest.raises(PilotlabError, match="on a Dask worker without that resource"):
            client.submit(check_on_its_machine, other, "timing y").result()


def test_a_recipe_cannot_give_a_built_in_profile_other_settings():
    """Outside test: `hardware: {cpu1: {threads: 2}}` was taken, every table saying "cpu1" of two threads."""
    from pilotlab.hardware import BUILTIN, profile_from_dict, recipe_profile
    with pytest.raises(PilotlabError, match=r"hardware.cpu1: 'cpu1' is a built-in profile \(cpu, 1 thread\); give a "
                                            r"profile of other settings a name of its own"):
        recipe_profile("cpu1", {"threads": 2})
    assert recipe_profile("cpu1", {"threads": 1}) == BUILTIN["cpu1"]        # the same settings: the same profile
    assert recipe_profile("cpu1_2t", {"threads": 2}).threads == 2
    assert profile_from_dict({"name": "cpu", "threads": 1}).threads == 1   # job params may narrow one (a lap's share)
