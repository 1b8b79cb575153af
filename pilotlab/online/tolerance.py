"""Latency tolerance: how much latency a brain can take on top of its own before it loses the lap.

    found = tolerance_search(lap, ToleranceSpec())     # lap(injected_ms) -> LapOutcome (pilotlab.specs.online)
    found["latency_tolerance_ms"], found["tolerance_laps"]

For one lap cell (brain, circuit, direction, hardware profile), the lap from the first start point is
driven again with more injected latency (`extra_latency_ms` on top of the brain's own, replayed or
measured). The result is the largest injected latency, on a grid of `step_ms` in 0..`max_ms`, at which
the lap is still completed, and the deviation of the laps at a few fixed injected latencies.

The search is cheap by construction:
- coarse then fine: the laps at the fixed latencies (needed for the deviation anyway) bracket the
  tolerance, then a search on the `step_ms` grid inside the bracket that drives its next lap `probe`
  of the way up (bisection at 0.5; above it, since a lost lap costs a fraction of a completed one);
- shared laps: a latency is never driven twice, and the plain lap (0 ms injected) is the cell's
  first run, already driven;
- early stop: a lap that leaves the road ends there (the env's stop rule), so lost laps cost a
  fraction of a lap; only completed ones cost a full lap;
- a hint: the tolerance of a neighbour cell (the same brain and latencies on the recipe's shortest
  circuit, pilotlab.planning.laps) is where a cell's tolerance usually is (the study's cells on Montreal
  within 10 ms of simple_circuit's in 22 of 24), so the search drives its next lap there, then one
  step on in the direction that lap points, strides doubling from the third: two laps when the hint is
  right, instead of the bisection's three to four (or the max_ms lap and six more above 200 ms). Such
  a cell drives no fixed latency first: below its tolerance each is a whole lap (slower than the plain
  one) that decides nothing the hint's laps do not; the fixed latencies' deviations are its neighbour's
  to report (the study's Montreal searches: 14,300 simulated seconds -> 10,000, the same tolerances).
The search assumes that a lap completed at some latency is completed at every smaller one; the laps at
the fixed latencies are reported, so a cell where that does not hold shows it.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pilotlab.specs.online import ToleranceSpec


@dataclass
class LapOutcome:
    injected_ms: float
    completed: bool
    metrics: dict[str, Any] = field(default_factory=dict)   # termination, deviations, sim_seconds, ...

    def as_dict(self) -> dict[str, Any]:
        return {"injected_ms": self.injected_ms, "lap_completed": self.completed, **self.metrics}


LapFn = Callable[[float], LapOutcome]


class _Laps:
    """Each injected latency driven at most once."""

    def __init__(self, lap: LapFn, known: dict[float, LapOutcome]):
        self.lap, self.outcomes = lap, dict(known)

    def completed(self, ms: float) -> bool:
        if ms not in self.outcomes:
            self.outcomes[ms] = self.lap(ms)
        return self.outcomes[ms].completed


def _bracket(laps: _Laps, fixed_ms: list[float]) -> tuple[float | None, float | None]:
    """(largest latency of the completed run of `fixed_ms` from 0, first lost one after it)."""
    completed, lost = None, None
    for ms in sorted({0.0, *fixed_ms}):
        if not laps.completed(ms):
            lost = ms
            break
        completed = ms
    return completed, lost


def _probe(low: float, high: float, settings: ToleranceSpec) -> float:
    """The grid point `probe` of the way from low to high, strictly between them."""
    steps = round((high - low) / settings.step_ms)
    return low + settings.step_ms * min(steps - 1, max(1, round(steps * settings.probe)))


def _from_hint(laps: _Laps, low: float, high: float | None, hint_ms: float,
               settings: ToleranceSpec) -> tuple[float, float | None]:
    """Narrow the bracket (low, high) starting at the hint: a lap there, then one step on in the
    direction its outcome points (up when completed), strides doubling from the third lap, until an
    outcome turns (the bisection finishes that bracket) or the bracket is one step wide. high None: not
    yet lost at any latency driven (the search's top is then max_ms)."""
    step = settings.step_ms
    upper = settings.max_ms + step if high is None else high    # above max_ms: "still completed at max_ms"
    probe, moves, went_up = round(hint_ms / step) * step, 0, None
    while upper - low > step + 1e-9:
        probe = min(max(probe, low + step), upper - step)
        completed = laps.completed(probe)
        low, upper = (probe, upper) if completed else (low, probe)
        if went_up is not None and completed != went_up:
            break
        went_up, moves = completed, moves + 1
        stride = step * 2 ** max(0, moves - 2)
        probe = probe + stride if completed else probe - stride
    return low, (None if upper > settings.max_ms else upper)


def tolerance_search(lap: LapFn, settings: ToleranceSpec = ToleranceSpec(),
                     known: dict[float, LapOutcome] | None = None, hint_ms: float | None = None) -> dict[str, Any]:
    """Drive `lap(injected_ms)` as needed; `known`: outcomes already driven (the plain lap at 0 ms);
    `hint_ms`: where the tolerance probably is (a neighbour cell's), searched from (instead of the
    fixed latencies first). latency_tolerance_ms is None when the lap is lost with nothing injected;
    tolerance_at_least is true when it was still completed at max_ms; tolerance_fixed_ms lists the
    fixed latencies driven."""
    laps = _Laps(lap, known or {})
    # from a hint, no fixed laps first: each one under the tolerance is a whole lap, and the hint brackets better
    low, high = _bracket(laps, settings.fixed_ms if hint_ms is None else [])
    if low is not None and hint_ms is not None:
        low, high = _from_hint(laps, low, high, hint_ms, settings)
    if low is not None and high is None:
        high = None if laps.completed(settings.max_ms) else settings.max_ms
        low = settings.max_ms if high is None else low
    while low is not None and high is not None and high - low > settings.step_ms + 1e-9:
        middle = _probe(low, high, settings)
        low, high = (middle, high) if laps.completed(middle) else (low, middle)
    outcomes = [laps.outcomes[ms].as_dict() for ms in sorted(laps.outcomes)]
    fixed = sorted(ms for ms in {0.0, *settings.fixed_ms} if ms in laps.outcomes)
    return {"latency_tolerance_ms": low, "tolerance_at_least": low is not None and high is None,
            "tolerance_fixed_ms": fixed, "tolerance_laps": outcomes,
            "tolerance_laps_driven": len(laps.outcomes) - len(known or {})}


SCORES = ("percentage_completed", "position_deviation_mae_m", "bm_position_deviation_mae", "bm_percentage_completed")


def lap_outcome(trajectory, injected_ms: float, checkpoints=None, scored: dict[str, Any] | None = None) -> LapOutcome:
    """The lap's completion and our deviation; BehaviorMetrics' too when `checkpoints` are given (the
    search's other laps skip them: only their completion counts). `scored`: this trajectory's metrics,
    already computed (the cell's first run: BehaviorMetrics' deviation is a tenth of a Montreal cell)."""
    from pilotlab.online.bm_metrics import bm_position_deviation_mae, bm_percentage_completed
    from pilotlab.online.metrics import lap_completed, percentage_completed, position_deviation_mae_m
    metrics = {"termination": trajectory.termination, "sim_seconds": round(float(trajectory.t[-1]), 3)}
    if scored is not None:
        return LapOutcome(injected_ms, lap_completed(trajectory), metrics | {k: scored.get(k) for k in SCORES})
    metrics |= {"percentage_completed": percentage_completed(trajectory),
                "position_deviation_mae_m": position_deviation_mae_m(trajectory)}
    if checkpoints is not None:
        metrics |= {"bm_position_deviation_mae": bm_position_deviation_mae(trajectory, checkpoints),
                    "bm_percentage_completed": bm_percentage_completed(trajectory, checkpoints)}
    return LapOutcome(injected_ms, lap_completed(trajectory), metrics)


def cell_tolerance(env, brain, spec, settings: ToleranceSpec, first, checkpoints, latency_ms=None,
                   progress: Callable[[float, float, str], None] | None = None,
                   first_scored: dict[str, Any] | None = None, hint_ms: float | None = None) -> dict[str, Any]:
    """The tolerance search of one lap cell in `env` (closed at the end): the laps from `first`'s
    start and seed (`first` is the cell's first run, driven with nothing more injected: the 0 ms lap;
    `first_scored`, its metrics if already computed; `hint_ms`, a neighbour cell's tolerance)."""
    from pilotlab.online.drive import drive
    start, seed = first.meta["start_m"], spec.seed

    def lap(injected_ms: float) -> LapOutcome:
        if progress is not None:
            progress(0.0, 1.0, f"{brain.name}: latency tolerance, lap with +{injected_ms:g} ms")
        settings_ms = spec.model_copy(update={"extra_latency_ms": spec.extra_latency_ms + injected_ms})
        trajectory = drive(env, brain, settings_ms, start=start, seed=seed, latency_ms=latency_ms)
        return lap_outcome(trajectory, injected_ms, checkpoints if injected_ms in settings.fixed_ms else None)

    try:
        return tolerance_search(lap, settings, known={0.0: lap_outcome(first, 0.0, checkpoints, first_scored)},
                                hint_ms=hint_ms)
    finally:
        env.close()
