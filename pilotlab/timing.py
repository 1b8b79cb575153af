"""Timing that interference cannot silently inflate.

Each call is timed with perf_counter_ns and, on Linux, paired with how long this process's threads
waited for a CPU around it (the run-queue wait, `run_delay` in /proc/self/task/*/schedstat): time
another process, or the hypervisor, held a core one of our threads was ready to run on. A call that
such a wait overlapped (more than a sliver of its wall time) is *disturbed*, even when the waiting
thread was a worker the call went on without; the figure is the median of the clean calls.

Calls run in blocks of at least `block_seconds`; around each block the process's CPU time and the
busy and steal time of our cores (/proc/stat) say how many cores other processes used, which the
result reports; where per-thread waits cannot be read (no schedstat, not Linux), a block is clean
when this process was on a CPU at least 90 % of its wall time and others left the cores it needs.

Disturbed calls are re-measured, up to `attempts` times the time budget. A figure is *stable* when at
least `min_calls` clean calls were had and they make at least `min_clean_share` of the calls (so a
few lucky calls never stand for a loaded run); otherwise it is the median of every call, marked
unstable with the reason, and a report draws no conclusion from it. Except on a single thread: there
(`cpu_clock`) each call's CPU time of the thread that makes it is taken too, and where the wall-clock
figure is not stable the figure is the median of those CPU times (clock "thread_cpu", said with the
reason): that time does not grow while the thread waits for a core. It stands for the calls only when
their work runs on that thread (its CPU time at least CPU_SHARE of their wall time less our waits).

As pyperf does, a figure comes with its spread (10th and 90th percentiles: interference only adds
time, so a mean ± std says less), how many calls it is made of, and why it is unstable where it is.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

CPU_SHARE = 0.8   # thread CPU time over (wall time - waits) of calls whose work runs on the calling thread


@dataclass(frozen=True)
class Limits:
    """How much waiting for a CPU a clean call may see, and how many clean calls a stable figure needs."""
    max_wait_share: float = 0.02      # run-queue wait of our threads over the call's wall time
    max_wait_ns: int = 20_000         # ... plus this much (a woken worker thread waits a few µs when quiet)
    min_clean_share: float = 0.25     # clean calls over all calls, for a stable figure
    max_other_cores: float = 0.3      # without per-thread waits: cores others may take beyond the free ones
    min_cpu_per_wall: float = 0.9     # ... and this process's CPU time over wall time (0 where it waits on a GPU)


@dataclass(frozen=True)
class Plan:
    """How long and how often one figure is measured."""
    min_calls: int = 300
    max_calls: int = 20_000
    min_blocks: int = 5
    block_seconds: float = 0.2
    seconds: float = 5.0              # the budget when nothing disturbs the measurement
    attempts: int = 3                 # disturbed calls are re-measured within attempts × seconds in all
    stable_within: float = 0.01       # stop early when the median moved less than this over a block


@dataclass(frozen=True)
class Snapshot:
    wall: float                       # perf_counter, s
    process: float                    # CPU time of this process (all threads), s
    busy: float | None                # busy time of our cores, every process, steal included, s
    steal: float | None               # of which steal, s


@dataclass(frozen=True)
class Load:
    """What happened on the CPU during one block."""
    seconds: float
    cpu_per_wall: float               # this process's CPU time over wall time
    others_cores: float | None        # cores used by other processes and steal (None without /proc/stat)
    steal_cores: float | None


@dataclass
class Block:
    times_ns: list[int]
    clean: list[bool]                 # per call: no wait of our threads for a CPU overlapped it
    load: Load
    cpu_ns: list[int] = field(default_factory=list)   # per call: CPU time of the calling thread (when asked)
    waited_ns: list[int] = field(default_factory=list)  # ... and our threads' run-queue wait read after it


@dataclass
class Measurement:
    """Every block of one figure, and which of its calls the figure is computed from."""
    cores: int
    needed_cores: int
    limits: Limits = Limits()
    min_calls: int = 300
    blocks: list[Block] = field(default_factory=list)
    cpu_clock: bool = False           # each call's thread CPU time was taken too (single-thread profiles)

    def times(self, clean_only: bool) -> np.ndarray:
        return np.asarray([t for b in self.blocks for t, ok in zip(b.times_ns, b.clean) if ok or not clean_only],
                          np.int64)

    @property
    def calls(self) -> int:
        return sum(len(b.times_ns) for b in self.blocks)

    @property
    def clean_calls(self) -> int:
        return sum(sum(b.clean) for b in self.blocks)

    @property
    def stable(self) -> bool:
        return self.clean_calls >= self.min_calls and self.clean_calls >= self.limits.min_clean_share * self.calls

    def cpu_times(self) -> np.ndarray:
        return np.asarray([t for b in self.blocks for t in b.cpu_ns], np.int64)

    @property
    def clock(self) -> str:
        """"wall", or "thread_cpu" where too few calls were clean and each call's work ran on the thread
        that made it (a single-thread profile): that thread's CPU time does not grow while it waits for
        a core, so it stands for the call where the wall clock cannot."""
        if self.stable or not self.cpu_clock or self.calls < self.min_calls:   # (a figure of 1 call was taken)
            return "wall"
        cpu = self.cpu_times()
        waited = np.asarray([w for b in self.blocks for w in b.waited_ns], np.int64)
        if len(cpu) != self.calls or len(waited) != self.calls:
            return "wall"
        running = np.maximum(self.times(clean_only=False) - waited, 0).sum()   # wall time not spent waiting
        return "thread_cpu" if cpu.sum() >= CPU_SHARE * running else "wall"

    def samples_ns(self) -> np.ndarray:
        """The calls the figure is made of, in measurement order: the clean ones; or, too few of them, every
        call's thread CPU time (clock "thread_cpu") or wall time (unstable)."""
        if self.clock == "thread_cpu":
            return self.cpu_times()
        return self.times(clean_only=self.stable)

    def cpu_time_reason(self) -> str | None:
        """Why the figure is the calls' thread CPU time (None when it is wall-clock time)."""
        if self.clock != "thread_cpu":
            return None
        return (f"{self.reason()}; so the figure is the CPU time of the thread that ran each call, which does not "
                "grow while the thread waits for a core (on a quiet machine it is wall-clock time)")

    def reason(self) -> str | None:
        """Why the figure is unstable (None when it is not)."""
        if self.stable:
            return None
        seconds = sum(b.load.seconds for b in self.blocks)
        share = 100 * self.clean_calls / max(1, self.calls)
        share_text = "<1" if 0 < share < 1 else f"{share:.0f}"
        load = self.summary()
        others = "" if load["others_cores"] is None else (
            f"; other processes used {load['others_cores']:.2f} of {self.cores} cores"
            + (f" (steal {load['steal_cores']:.2f})" if (load["steal_cores"] or 0) >= 0.005 else "")
            + f" beside the {self.needed_cores} this timing needs")
        # a single-thread figure falls back to CPU time only from min_calls calls (outside test: its throughput,
        # 7 calls of a batch, was left unstable without a word of why)
        few = (f"; too few calls ({self.calls}) for a CPU-time figure either (it needs {self.min_calls})"
               if self.cpu_clock and self.calls < self.min_calls else "")
        return (f"only {self.clean_calls} of {self.calls} calls ({share_text} %) ran with no thread of this "
                f"process waiting for a CPU (a stable figure needs {self.min_calls} such calls, and "
                f"{self.limits.min_clean_share:.0%} of all) in {seconds:.1f} s of measuring and re-measuring"
                f"{others}{few}")

    def summary(self) -> dict:
        """How the figure was measured: blocks, calls set aside, this process's CPU time over wall time,
        cores used by others and steal (averages over the blocks; None where /proc/stat is missing)."""
        seconds = sum(b.load.seconds for b in self.blocks) or 1e-9

        def mean(name: str) -> float | None:
            values = [(getattr(b.load, name), b.load.seconds) for b in self.blocks]
            if not values or any(v is None for v, _ in values):
                return None
            return sum(v * s for v, s in values) / seconds
        return {"blocks": len(self.blocks), "discarded": self.calls - self.clean_calls,
                "cpu_per_wall": mean("cpu_per_wall"), "others_cores": mean("others_cores"),
                "steal_cores": mean("steal_cores")}


def measure(call: Callable[[], object], needed_cores: int, plan: Plan = Plan(), limits: Limits = Limits(),
            cpu_clock: bool = False) -> Measurement:
    """Time `call` in blocks (see the module docstring) until `plan` is met or its budget is spent;
    `cpu_clock` (single-thread timings): each call's thread CPU time too."""
    result = Measurement(len(our_cpus()), needed_cores, limits, plan.min_calls, cpu_clock=cpu_clock)
    start = time.perf_counter()
    previous = None
    while True:
        result.blocks.append(timed_block(call, plan.block_seconds, needed_cores, limits, cpu_clock))
        elapsed = time.perf_counter() - start
        if result.calls >= plan.max_calls or elapsed > plan.seconds * plan.attempts:
            return result
        if len(result.blocks) >= plan.min_blocks and (result.stable or result.clock == "thread_cpu"):
            median = float(np.median(result.samples_ns()))
            settled = previous is not None and abs(median - previous) <= plan.stable_within * median
            if settled or elapsed > plan.seconds:
                return result
            previous = median


def timed_block(call: Callable[[], object], seconds: float, needed_cores: int, limits: Limits,
                cpu_clock: bool = False) -> Block:
    """Calls of `call` for at least `seconds`, each timed with its threads' run-queue wait (and with
    `cpu_clock`, its thread CPU time); the block's load."""
    before = snapshot()
    with ThreadWaits() as waits:
        per_call = waits.available
        times, clean, cpu, waited = _timed_calls(call, waits, limits, seconds=seconds, cpu_clock=cpu_clock)
    load = load_between(before, snapshot())
    if not per_call:    # no per-thread waits: judge the block by the cores others used
        ok = block_is_quiet(load, needed_cores, len(our_cpus()), limits)
        clean = [ok] * len(times)
    return Block(times, clean, load, cpu, waited if cpu_clock else [])


def _timed_calls(call: Callable[[], object], waits: ThreadWaits, limits: Limits, seconds: float,
                 cpu_clock: bool = False) -> tuple[list[int], list[bool], list[int], list[int]]:
    """Each call's wall time, whether it is clean (no wait of our threads overlapped it), with
    `cpu_clock` its thread CPU time (else []), and the wait of our threads read after it."""
    clock, thread_clock = time.perf_counter_ns, time.thread_time_ns
    begins, ends, waited, cpu = [], [], [], []
    end = clock() + int(seconds * 1e9)
    total = waits.total()
    while True:
        thread_begin = thread_clock() if cpu_clock else 0
        begin = clock()
        call()
        finished = clock()
        if cpu_clock:
            cpu.append(thread_clock() - thread_begin)
        now = waits.total()
        begins.append(begin)
        ends.append(finished)
        waited.append(now - total)
        total = now
        if finished >= end:
            times = [e - b for b, e in zip(begins, ends)]
            return times, clean_calls(np.asarray(begins), np.asarray(ends), np.asarray(waited), limits), cpu, waited


def clean_calls(begins: np.ndarray, ends: np.ndarray, waited: np.ndarray, limits: Limits) -> list[bool]:
    """Which calls no wait of our threads overlapped.

    A thread's run-queue wait is counted only once the thread runs again, so a wait read after call j
    (`waited[j]`, ns) may have begun before call j: up to `waited[j]` before the previous reading.
    Every call that overlaps that span is marked, unless the wait is a sliver of its wall time (a woken
    worker thread waits a few µs on an idle machine)."""
    clean = np.ones(len(ends), bool)
    previous = np.concatenate([begins[:1], ends[:-1]])
    walls = ends - begins
    for j in np.flatnonzero(waited > limits.max_wait_ns):
        start = previous[j] - waited[j]
        first = int(np.searchsorted(ends, start))           # the first call that ends after the wait began
        span = slice(first, j + 1)
        clean[span] &= waited[j] <= limits.max_wait_ns + limits.max_wait_share * walls[span]
    return clean.tolist()


def block_is_quiet(load: Load, needed_cores: int, cores: int, limits: Limits = Limits()) -> bool:
    """Where per-thread waits cannot be read: this process was on a CPU nearly all the block, and other
    processes (where /proc/stat says) left the cores the timing needs."""
    if load.cpu_per_wall < limits.min_cpu_per_wall:
        return False
    return load.others_cores is None or load.others_cores <= max(0, cores - needed_cores) + limits.max_other_cores


class ThreadWaits:
    """The summed run-queue wait (ns) of this process's threads, read from /proc/self/task/*/schedstat
    through descriptors opened once per block; `available` is False where the kernel does not say."""

    def __init__(self):
        self._fds: list[int] = []

    def __enter__(self) -> ThreadWaits:
        for task in _list(Path("/proc/self/task")):
            try:
                self._fds.append(os.open(f"/proc/self/task/{task}/schedstat", os.O_RDONLY))
            except OSError:
                continue
        return self

    def __exit__(self, *_exc) -> None:
        for fd in self._fds:
            os.close(fd)
        self._fds = []

    @property
    def available(self) -> bool:
        return bool(self._fds)

    def total(self) -> int:
        waited = 0
        for fd in self._fds:
            try:
                waited += int(os.pread(fd, 128, 0).split()[1])
            except (OSError, IndexError, ValueError):   # the thread ended
                continue
        return waited


def load_between(before: Snapshot, after: Snapshot) -> Load:
    wall = max(after.wall - before.wall, 1e-9)
    mine = after.process - before.process
    if before.busy is None or after.busy is None:
        return Load(wall, mine / wall, None, None)
    others = max(0.0, (after.busy - before.busy) - mine) / wall
    return Load(wall, mine / wall, others, max(0.0, after.steal - before.steal) / wall)


def snapshot() -> Snapshot:
    stat = cpu_stat()
    return Snapshot(time.perf_counter(), time.process_time(), *(stat if stat else (None, None)))


def cpu_stat(path: Path = Path("/proc/stat")) -> tuple[float, float] | None:
    """(busy, steal) seconds of the cores this process may run on, or None where /proc/stat is missing."""
    try:
        lines = path.read_text().splitlines()
    except OSError:
        return None
    wanted = {f"cpu{n}" for n in our_cpus()}
    busy = steal = 0
    for line in lines:
        fields = line.split()
        if fields and fields[0] in wanted:
            # user nice system idle iowait irq softirq steal (guest time is already in user)
            values = [int(v) for v in fields[1:9]]
            busy += sum(values) - values[3] - values[4]
            steal += values[7]
    tick = os.sysconf("SC_CLK_TCK")
    return busy / tick, steal / tick


@cache
def our_cpus() -> tuple[int, ...]:
    try:
        return tuple(sorted(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return tuple(range(os.cpu_count() or 1))


def _list(folder: Path) -> list[str]:
    try:
        return os.listdir(folder)
    except OSError:
        return []
