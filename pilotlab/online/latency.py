"""Latency samples a lap replays: what one brain iteration costs on a hardware profile, measured once.

    samples = timing_samples(timing_job_artifacts, timing_result)         # the timing job's
    samples = latency_file_samples("timings/jetson.csv", model="pilotnet", strategy="baseline")
    draws = LatencyDraws(samples, seed=0); draws.next_s()                  # seconds, seeded

The `replay` timing mode (pilotlab.online.drive) charges each brain iteration a latency drawn
(uniformly, with replacement, from a seeded generator) from these samples, so a lap does not depend on
how loaded the simulating host is, and a lap can be driven for hardware that is not this host.

Two sources:
- the timing job of the same artifact on the same hardware profile: its artifacts hold
  `latency_ms.npy` (float64 milliseconds, one per timed batch-1 predict call), named by its result's
  `latency_samples`;
- a latency file the user measured on a device (`hardware: {jetson: {latency_file: timings/jetson.csv}}`):
  a CSV with a header and a `latency_ms` column (milliseconds, one sample a row), optionally `model`
  and `strategy` columns. A lap takes the rows of its model and strategy; rows with an empty (or `*`)
  strategy apply to every strategy, an empty model to every model; the most specific match wins
  (model and strategy, then strategy, then model, then neither). `#` comments are allowed.
"""
from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pilotlab.errors import PilotlabError

SAMPLES_FILE = "latency_ms.npy"
RESULT_KEY = "latency_samples"
MAX_MS = 60_000.0   # as the lap settings' extra_latency_ms and fixed_inference_ms: a brain iteration a
                    # minute long is no lap (a sample of 1e9 ms ran one for hours)


def check_samples(samples: np.ndarray, where: str) -> np.ndarray:
    samples = np.asarray(samples, dtype=np.float64).ravel()
    if not len(samples) or not np.all(np.isfinite(samples)) or np.any(samples < 0) or np.any(samples > MAX_MS):
        largest = f", the largest {samples.max():g}" if len(samples) and np.all(np.isfinite(samples)) else ""
        raise PilotlabError(f"{where}: latency samples must be finite milliseconds from 0 to {MAX_MS:g}, at least "
                            f"one; got {len(samples)} sample(s){largest}")
    return samples


def timing_samples(artifacts: Path, result: Mapping[str, Any]) -> np.ndarray:
    """The batch-1 latency samples the timing job kept."""
    name = result.get(RESULT_KEY)
    if not name:
        raise PilotlabError(f"the timing job in {artifacts} kept no latency samples (its result has no "
                            f"{RESULT_KEY!r}); rerun it with `pilotlab run --force timing`")
    path = Path(artifacts) / name
    if not path.is_file():
        raise PilotlabError(f"{path}: the timing job's latency samples are missing; rerun it with "
                            "`pilotlab run --force timing`")
    return check_samples(np.load(path), str(path))


FORMAT = ("a latency file is a CSV (UTF-8 text) with a header and a latency_ms column (optionally model and "
          "strategy); see docs/simulator.md")


def read_latency_file(path: Path) -> list[dict[str, str]]:
    """The rows of a latency file, each latency_ms checked (a number of milliseconds in range)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
        lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
        rows = list(csv.DictReader(lines))
    except (UnicodeDecodeError, csv.Error) as error:
        raise PilotlabError(f"{path}: cannot be read ({error}); {FORMAT}") from None
    if not rows or "latency_ms" not in rows[0]:
        raise PilotlabError(f"{path}: {FORMAT}")
    values = []
    for number, row in enumerate(rows, 1):
        try:
            values.append(float(row["latency_ms"]))
        except (TypeError, ValueError):
            raise PilotlabError(f"{path}: row {number} of the data ({row}): latency_ms must be a number of "
                                "milliseconds in every row") from None
    check_samples(np.array(values), str(path))
    return rows


def latency_file_samples(path: Path, model: str | None, strategy: str | None,
                         rows: list[dict[str, str]] | None = None) -> np.ndarray:
    """The samples of `model`/`strategy` in a user's latency file (the most specific rows that match);
    `rows`: the file's, read already."""
    rows = read_latency_file(path) if rows is None else rows
    wild = lambda value: (value or "").strip() in ("", "*")
    matches = {rank: [] for rank in range(4)}
    for row in rows:
        row_model, row_strategy = (row.get("model") or "").strip(), (row.get("strategy") or "").strip()
        if not (wild(row_model) or row_model == model) or not (wild(row_strategy) or row_strategy == strategy):
            continue
        matches[(0 if wild(row_strategy) else 2) + (0 if wild(row_model) else 1)].append(row["latency_ms"])
    best = next((values for rank, values in sorted(matches.items(), reverse=True) if values), None)
    if best is None:
        raise PilotlabError(f"{path}: no latency_ms rows for model {model!r}, strategy {strategy!r}; add rows for "
                            "them (or rows with an empty strategy for every strategy)")
    return check_samples(np.array([float(value) for value in best]), str(path))


class LatencyDraws:
    """Seeded draws from the samples: the latency charged to each brain iteration of one run."""

    def __init__(self, samples_ms: np.ndarray, seed: int):
        self.samples_ms = check_samples(samples_ms, "replayed latency")
        self.rng = np.random.default_rng(seed)

    def next_s(self) -> float:
        return float(self.samples_ms[self.rng.integers(len(self.samples_ms))]) / 1000.0


STALL_TIMES_MEDIAN = 3.0   # a sample this far above its median is the host stalling the call (preempted, a
                           # page fault), not the network's work: 2 of 1,073 calls of one study timing (3.2
                           # and 8.6 ms against 0.95) whose laps, scaled ×127, froze the car for a second


def scale_to(samples_ms: np.ndarray, reference_ms: np.ndarray, target_ms: float) -> tuple[np.ndarray, float, int]:
    """`samples_ms` on a device k× slower than the one measured, k chosen so the reference's median
    becomes `target_ms` (the study recipe: the baseline at the study's 124 ms); (samples, k, stalls).

    A stall (a sample over STALL_TIMES_MEDIAN × the samples' median) is time the host took, not work the
    network did; a slower device would not stall k× longer. It is replayed as the median's work scaled
    plus the stall's own excess, unscaled."""
    median = float(np.median(check_samples(reference_ms, "reference latency")))
    if median <= 0 or not target_ms > 0:
        raise PilotlabError(f"cannot scale latencies to {target_ms} ms from a reference median of {median} ms")
    factor = target_ms / median
    samples = check_samples(samples_ms, "replayed latency")
    own_median = float(np.median(samples))
    stalled = samples > STALL_TIMES_MEDIAN * own_median
    scaled = samples * factor
    scaled[stalled] = own_median * factor + (samples[stalled] - own_median)
    return scaled, factor, int(stalled.sum())


def describe(samples_ms: np.ndarray, source: str, factor: float = 1.0, stalls: int = 0) -> dict[str, Any]:
    """What the result says of the replayed latencies."""
    described = {"latency_source": source, "replayed_latency_ms": round(float(np.median(samples_ms)), 4),
                 "replayed_latency_p90_ms": round(float(np.percentile(samples_ms, 90)), 4),
                 "replayed_latency_samples": int(len(samples_ms))}
    return described | ({"latency_scale": round(factor, 6), "replayed_stalls": stalls} if factor != 1.0 else {})


@dataclass(frozen=True)
class TimingSource:
    """Where a lap's latency samples come from (what the online job's deps and inputs give it)."""
    timing: tuple[Path, Mapping[str, Any]] | None = None         # the timing job's (artifacts, result)
    latency_file: Path | None = None                              # a user's latency file
    model: str | None = None                                      # the rows of the latency file to take
    strategy: str | None = None
    scale_to_ms: float | None = None                              # emulate a device where `reference` takes this
    reference: tuple[Path, Mapping[str, Any]] | None = None       # the baseline's timing job (artifacts, result)
    reference_strategy: str = "baseline"

    def _own(self) -> tuple[np.ndarray, str]:
        if self.latency_file is not None:
            return latency_file_samples(self.latency_file, self.model, self.strategy), \
                f"latency file {Path(self.latency_file).name}"
        if self.timing is not None:
            return timing_samples(*self.timing), "timing job"
        raise PilotlabError("the replay timing mode needs the timing job of the same artifact and hardware "
                            "profile (dependency 'timing') or a hardware profile's latency_file")

    def _reference(self) -> np.ndarray:
        if self.latency_file is not None:
            return latency_file_samples(self.latency_file, self.model, self.reference_strategy)
        if self.reference is None:
            raise PilotlabError(f"scaling latencies to {self.scale_to_ms} ms needs the {self.reference_strategy} "
                                "strategy's timing job (dependency 'scale_reference')")
        return timing_samples(*self.reference)

    def samples(self) -> tuple[np.ndarray, dict[str, Any]]:
        """(samples in ms, what the result says of them)."""
        samples, source = self._own()
        if self.scale_to_ms is None:
            return samples, describe(samples, source)
        scaled, factor, stalls = scale_to(samples, self._reference(), self.scale_to_ms)
        source += f", scaled ×{factor:.3g} so that {self.reference_strategy} takes {self.scale_to_ms:g} ms"
        if stalls:
            source += f" ({stalls} host stall{'s' * (stalls > 1)} replayed unscaled)"
        return scaled, describe(scaled, source, factor, stalls)


def measure_samples(brain, runs: int = 200) -> np.ndarray:
    """Batch-1 latencies (ms) of a network brain's predict call on this host, timed once before a lap
    (`pilotlab drive` without a timing job): the lap then replays them."""
    import time
    blank = np.zeros((1, 3 * brain.frames, brain.config.height, brain.config.width), np.float32)
    brain.warm_up()
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        brain.predictor.predict(blank)
        times.append(1000.0 * (time.perf_counter() - started))
    return np.asarray(times)
