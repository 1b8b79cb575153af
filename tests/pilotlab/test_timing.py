"""Timing under interference: which calls are clean, when a figure is unstable, and the flag itself
raised by real CPU hogs beside a real timing."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pilotlab import offline, timing
from pilotlab.timing import Block, Limits, Load, Measurement

QUIET = Load(0.2, 1.0, 0.05, 0.0)
BUSY = Load(0.2, 0.4, 1.6, 0.1)


def block(clean: list[bool], load: Load = QUIET, time_ns: int = 1_000_000) -> Block:
    return Block([time_ns] * len(clean), clean, load)


def test_the_figure_comes_from_the_clean_calls_when_there_are_enough():
    measured = Measurement(2, 2, Limits(min_clean_share=0.25), min_calls=4,
                           blocks=[block([True, False, True]), block([True, True, False], time_ns=3_000_000)])
    assert measured.stable and measured.reason() is None
    assert list(measured.samples_ns()) == [1_000_000, 1_000_000, 3_000_000, 3_000_000]   # in order
    assert measured.summary()["discarded"] == 2


def test_too_few_clean_calls_make_the_figure_unstable_with_the_reason():
    few = Measurement(2, 2, Limits(min_clean_share=0.25), min_calls=4, blocks=[block([True] * 3 + [False] * 9, BUSY)])
    assert not few.stable and len(few.samples_ns()) == 12                  # every call, marked unstable
    assert few.reason().startswith("only 3 of 12 calls (25 %) ran with no thread of this process waiting for a CPU")
    assert "other processes used 1.60 of 2 cores (steal 0.10) beside the 2 this timing needs" in few.reason()
    lucky = Measurement(2, 2, Limits(min_clean_share=0.25), min_calls=4, blocks=[block([True] * 4 + [False] * 16)])
    assert not lucky.stable                                                # 4 lucky calls never stand for a loaded run


def test_a_wait_marks_every_call_it_may_have_overlapped():
    """Calls of 1 ms each, 0.1 ms apart. A wait is read once the waiting thread runs again: 2.5 ms read
    after call 4 may have begun 2.5 ms before the reading after call 3, so calls 1 to 4 are marked."""
    begins = np.arange(6) * 1_100_000
    ends = begins + 1_000_000
    waited = np.array([0, 5_000, 0, 0, 2_500_000, 0])          # 5 µs: a woken worker on an idle machine
    assert timing.clean_calls(begins, ends, waited, Limits()) == [True, False, False, False, False, True]
    long_calls = timing.clean_calls(begins, begins + 1_000_000_000, np.array([0, 0, 0, 0, 2_500_000, 0]), Limits())
    assert all(long_calls)                                     # 2.5 ms is a sliver of a 1 s call


def test_without_per_thread_waits_a_block_is_judged_by_its_cpu_time_and_the_cores_others_used():
    assert timing.block_is_quiet(QUIET, needed_cores=2, cores=2)
    assert not timing.block_is_quiet(BUSY, needed_cores=2, cores=2)
    assert timing.block_is_quiet(Load(0.2, 1.0, 1.2, 0.0), needed_cores=1, cores=2)   # one core is free for them
    assert not timing.block_is_quiet(Load(0.2, 0.6, None, None), needed_cores=1, cores=2)  # off the CPU 40 %
    assert timing.block_is_quiet(Load(0.2, 0.6, None, None), 1, 2, Limits(min_cpu_per_wall=0.0))  # waits on a GPU


def test_a_disturbed_single_thread_figure_is_its_thread_cpu_time_with_the_reason():
    # calls of 1 ms of work that waited 2 ms each for a core
    waited = [Block([3_000_000] * 8, [False] * 8, BUSY, cpu_ns=[1_000_000] * 7 + [1_100_000],
                    waited_ns=[2_000_000] * 8)]
    single = Measurement(2, 1, Limits(), min_calls=4, blocks=waited, cpu_clock=True)
    assert not single.stable and single.clock == "thread_cpu"
    assert list(single.samples_ns()) == [1_000_000] * 7 + [1_100_000]
    assert single.cpu_time_reason().startswith(single.reason() + "; so the figure is the CPU time of the thread")
    assert offline.clock_notes(single, "latency_ms") == {"unstable": {}, "cpu_time": {
        "latency_ms": single.cpu_time_reason()}}
    # the work ran on other threads (the calling one only waited): its CPU time says nothing of the call
    elsewhere = Measurement(2, 1, Limits(), min_calls=4, cpu_clock=True,
                            blocks=[Block([3_000_000] * 8, [False] * 8, BUSY, cpu_ns=[50_000] * 8,
                                          waited_ns=[1_000_000] * 8)])
    assert elsewhere.clock == "wall" and elsewhere.cpu_time_reason() is None
    assert offline.clock_notes(elsewhere, "latency_ms")["unstable"] == {"latency_ms": elsewhere.reason()}
    quiet = Measurement(2, 1, Limits(), min_calls=4, cpu_clock=True,
                        blocks=[Block([3_000_000] * 8, [True] * 8, QUIET, cpu_ns=[1_000_000] * 8)])
    assert quiet.clock == "wall" and list(quiet.samples_ns()) == [3_000_000] * 8      # the default when quiet
    # outside test: a throughput figure of one batch call was taken as CPU time, unmarked; fewer calls than
    # a figure needs are an unstable figure, whatever the clock, and the reason says what it needs
    one = Measurement(2, 1, Limits(), min_calls=4, blocks=[Block(
        [3_000_000], [False], BUSY, cpu_ns=[1_000_000], waited_ns=[2_000_000])], cpu_clock=True)
    assert one.clock == "wall" and not one.stable
    assert "(a stable figure needs 4 such calls, and 25% of all)" in one.reason()
    assert one.reason().endswith("; too few calls (1) for a CPU-time figure either (it needs 4)")   # outside test K10
    assert "too few calls" not in elsewhere.reason()


def spin(microseconds: int):
    """A call whose work is on the calling thread: it spins until that thread used `microseconds` of CPU."""
    started = time.thread_time_ns()
    while time.thread_time_ns() - started < microseconds * 1000:
        pass


def test_thread_cpu_time_is_taken_per_call_and_stands_only_for_work_on_the_calling_thread():
    every_call_waited = Limits(max_wait_ns=-1, max_wait_share=-1.0)   # as if another process held the core
    plan = timing.Plan(min_calls=20, max_calls=200, min_blocks=2, block_seconds=0.01, seconds=0.2, attempts=1)
    spun = timing.measure(lambda: spin(300), 1, plan, every_call_waited, cpu_clock=True)
    assert spun.clean_calls == 0 and spun.clock == "thread_cpu"
    assert all(len(b.cpu_ns) == len(b.times_ns) for b in spun.blocks)
    assert np.median(spun.samples_ns()) >= 300_000
    slept = timing.measure(lambda: time.sleep(0.001), 1, plan, every_call_waited, cpu_clock=True)
    assert slept.clock == "wall" and not slept.stable                  # asleep, the thread used no CPU: unstable
    wall_only = timing.measure(lambda: spin(300), 1, plan, every_call_waited)
    assert wall_only.clock == "wall" and not wall_only.blocks[0].cpu_ns


def test_cpu_stat_sums_busy_and_steal_of_our_cores(tmp_path):
    stat = tmp_path / "stat"
    lines = ["cpu  999 0 999 999 0 0 0 0 0 0"] + [f"cpu{n} 100 0 50 800 30 0 10 40 0 0" for n in range(256)]
    stat.write_text("\n".join(lines) + "\n")
    busy, steal = timing.cpu_stat(stat)
    tick, cores = os.sysconf("SC_CLK_TCK"), len(timing.our_cpus())
    assert busy == pytest.approx(cores * 200 / tick) and steal == pytest.approx(cores * 40 / tick)


HOGGED_TIMING = """
import json, os, sys
os.sched_setaffinity(0, json.loads(sys.argv[1]))      # the two cores the hogs spin on
import torch
from pilotlab.hardware import HardwareProfile, apply_profile
from pilotlab.offline import TimingSettings, measure_latency
profile = HardwareProfile("cpu2", "cpu", 2)
apply_profile(profile)
model = torch.nn.Sequential(torch.nn.Conv2d(3, 8, 5, 2), torch.nn.ReLU(), torch.nn.Flatten(),
                            torch.nn.LazyLinear(2)).eval()
def predict(batch):
    with torch.inference_mode():
        return model(torch.from_numpy(batch))
import numpy as np
batch = np.zeros((1, 3, 66, 200), np.float32)
predict(batch)
sys.stdout.write("ready\\n"); sys.stdout.flush(); sys.stdin.readline()
settings = TimingSettings(warmup_runs=5, warmup_seconds=0.0, min_runs=50, max_seconds=0.5, block_seconds=0.05,
                          attempts=2)
result = measure_latency(predict, batch, settings, profile)
print(json.dumps({k: v for k, v in result.items() if k != "samples_ms"}))
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="per-thread run-queue waits are Linux only")
@pytest.mark.skipif(len(timing.our_cpus()) < 2, reason="the profile times on 2 threads")
def test_a_timing_beside_cpu_hogs_is_marked_unstable(tmp_path):
    """Two processes spin on both cores while a tiny model is timed on 2 threads there: the latency
    is marked unstable, with the reason, instead of being reported as a clean figure."""
    cores = list(timing.our_cpus()[:2])
    timed = subprocess.Popen([sys.executable, "-c", HOGGED_TIMING, json.dumps(cores)], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True,
                             env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    hogs = []
    try:
        assert timed.stdout.readline().strip() == "ready"
        hogs = [subprocess.Popen([sys.executable, "-c", f"import os; os.sched_setaffinity(0, {cores}); "
                                  "exec('while 1: pass')"]) for _ in cores]
        output, _ = timed.communicate("go\n", timeout=120)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
        timed.kill()
    result = json.loads(output.splitlines()[-1])
    reason = result["unstable"]["latency_ms"]
    assert "ran with no thread of this process waiting for a CPU" in reason and "other processes used" in reason, reason
    # the hogs share the two cores with this timing, so they get about one of them between them
    assert result["timing_calls_discarded"] > 0 and result["timing_other_cores"] > 0.5
