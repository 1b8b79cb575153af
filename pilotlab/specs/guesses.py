"""What a job of each kind typically takes, for the scheduler and the time left of a store that has not
run it yet (matrix.times: once a store has run a kind, its own figures scale these); what `plan` says
of a job beside its state (a lap's tolerance search, a CUDA job that ends at once on a host without a
GPU); and, at the end, which keys of its results measure how the run went (wall-clock time), not what it
made.

A guess is never part of a job's key, and here it is not part of any kind's code either: no handler
and no params model imports this module (a test checks it), so tuning a guess re-keys no job. Written
in the kinds' own modules, a guess was their code: editing the lap cell's guess made every lap stale.
Only guesses (and the measured keys, which no result depends on either) belong here; anything a job's
result depends on belongs to the kind's modules.

Each figure was measured on a 2-core development machine (which one and when is said beside it).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from matrix.kinds import guess_kind, measured_keys, note_kind
from pilotlab.circuits.registry import lap_scale
from pilotlab.specs.online import LapSettings, ToleranceSpec
from pilotlab.specs.record import RecordSpec
from pilotlab.specs.timing import planned_without_gpu
from pilotlab.specs.train import TrainSpec
from pilotlab.strategies import PREPARATIONS, STRATEGIES

# A job for a CUDA profile, planned on a host without a GPU, says "not applicable" at once.
NOT_HERE_S = 0.1


def guess_here(seconds_for: Callable[[Any], float]) -> Callable[[Any], float]:
    """A kind's guess that knows a job that cannot run on its planned host ends at once."""
    return lambda params: NOT_HERE_S if planned_without_gpu(params) else seconds_for(params)


# record: a lap of simple_circuit at 640×480 took 2.7-3.5 s, other circuits by their length (the study's
# cold run of f6cb60d, 2026-12-02: many_curves 5.3-5.6 s, Montreal 7.8 s, 2.4-2.8 s a simple_circuit lap's worth)
RECORD_LAP_S = 2.8


def record_seconds(params) -> float:
    laps = float(params.get("laps", RecordSpec.model_fields["laps"].default))
    return RECORD_LAP_S * lap_scale(str(params.get("circuit", ""))) * laps


# frames: a one-lap recording read in 3-4 s on 2 cores.
FRAMES_S = 3.0

# train: PilotNet, a thousand frames, took 3 s an epoch.
TRAIN_EPOCH_S = 3.0


def train_seconds(params) -> float:
    return TRAIN_EPOCH_S * int(params.get("epochs", TrainSpec.model_fields["epochs"].default))


# optimize and prepare, on one core: a conversion 1-4 s, a calibration ~2 s more, and each epoch of
# fine-tuning (pruning, clustering; a strategy's *epochs options) 3-4 s on the study's 3,000 frames in
# bf16. A QAT epoch fine-tunes in fp32 with fake quantization (pilotlab.strategies.common.finetune): 9-13 s
# in the study's cold run of 70b1105 (Intel host, 2026-12-02), where, guessed at 3.5 s, they had the CQAT
# fine-tune (31 s, guessed 15) hold a timing up while a core idled. A channel-pruned network's epoch costs
# about its share of channels kept: 1.1 s at amount 0.65 (its stem subsampled), 2.2 s at 0.3.
BASE_S, CALIBRATION_S, EPOCH_S, QAT_EPOCH_S = 3.0, 2.0, 3.5, 10.5
FAKE_QUANT_EPOCHS = "qat_epochs"       # and the `qat` strategy's finetune_epochs: its fine-tune is QAT
CHANNEL_PRUNING = ("channel_pruning", "structured_prune")


def prepared_options(strategy: str | None) -> dict:
    """The options of the network a strategy's prepare job makes for it ({} when it prepares none)."""
    entry = STRATEGIES.get(strategy) if strategy in STRATEGIES else None
    return PREPARATIONS.get(entry.prepared_by).defaults if entry is not None and entry.prepared_by else {}


def epochs_seconds(options: dict, method: str | None, skip: dict | None = None) -> float:
    """Seconds of the *epochs options of a strategy or preparation (`method`), but for those in `skip`."""
    seconds = 0.0
    for name, value in options.items():
        if not name.endswith("epochs") or not isinstance(value, int) or name in (skip or {}):
            continue
        fake_quant = name == FAKE_QUANT_EPOCHS or (method == "qat" and name == "finetune_epochs")
        kept = 1.0 - float(options.get("amount", 0.0)) if method in CHANNEL_PRUNING else 1.0
        seconds += value * (QAT_EPOCH_S if fake_quant else EPOCH_S * kept)
    return seconds


def optimize_seconds(params) -> float:
    """The epochs of a shared preparation are its prepare job's, not this job's."""
    options, strategy = params.get("options") or {}, params.get("strategy")
    return (BASE_S + (CALIBRATION_S if options.get("calibration_frames") else 0.0)
            + epochs_seconds(options, strategy, skip=prepared_options(strategy)))


def prepare_seconds(params) -> float:
    return BASE_S + epochs_seconds(params.get("options") or {}, params.get("preparation"))


# timing: about 2 s, most of it the measuring itself; offline: a test set of a few hundred frames.
TIMING_S, OFFLINE_S = 2.0, 1.0

# online: as measured in the study's cold run of f6cb60d (2026-12-02; laps have grown dearer since the
# 0.65 s of 2026-11-28: BehaviorMetrics' metrics and the trajectory picture of every lap): a network's
# lap of Montreal with replayed timing, driving on its view, 3.8-8.9 s (6.2 on average), simple_circuit's
# 2-4.6 s in the quickstart (its first lap in a worker pays the imports), other circuits by their length
# (Montreal 3.3 times). A tolerance search drives a lap per fixed latency above 0 and the bisection's, each
# 0.55 of a plain lap's job time on average (the study's searched cells on simple_circuit: 4-12 s, 6.4 on
# average): the completed ones take longer (the car slows as latency grows), the lost ones end where the
# car leaves the road, and the cell's setting up and metrics are paid once. A search from a neighbour's
# hint (pilotlab.online.tolerance) drives fewer, which the params do not say. Guessed 2.6 times short, the
# quickstart's explicit lap (guessed 1.2 s, took 4.1) was started beside the last recording, and the
# training waited 2.8 s for it.
SETUP_S, LAP_S, SEARCH_SHARE = 1.0, 1.5, 0.55


def search_laps(tolerance: ToleranceSpec) -> float:
    """Plain laps' worth of job time a tolerance search adds to its cell."""
    fixed = len({ms for ms in tolerance.fixed_ms if ms > 0})
    return SEARCH_SHARE * (fixed + tolerance.bisection_laps)


def online_seconds(params) -> float:
    settings = LapSettings.model_validate({k: params[k] for k in ("laps", "repetitions", "starts", "tolerance")
                                           if k in params})
    searched = 0 if settings.tolerance is None else search_laps(settings.tolerance)
    return SETUP_S + LAP_S * lap_scale(str(params.get("circuit", ""))) * settings.laps * settings.runs * (1 + searched)


guess_kind("record", typical_for=record_seconds)
guess_kind("frames", typical_s=FRAMES_S)
guess_kind("train", typical_for=train_seconds)
guess_kind("prepare", typical_for=prepare_seconds)
guess_kind("optimize", typical_for=guess_here(optimize_seconds))
guess_kind("timing", typical_for=guess_here(lambda params: TIMING_S))
guess_kind("offline", typical_for=guess_here(lambda params: OFFLINE_S))
guess_kind("online", typical_for=guess_here(online_seconds))

NO_GPU_NOTE = "not applicable here: no GPU on this host"


def cuda_note(params) -> str | None:
    return NO_GPU_NOTE if planned_without_gpu(params) else None


def lap_note(params) -> str | None:
    """A lap's tolerance search (several laps' worth of driving), or that it will not run here."""
    return cuda_note(params) or ("latency tolerance search" if params.get("tolerance") is not None else None)


for kind in ("optimize", "timing", "offline"):
    note_kind(kind, cuda_note)
note_kind("online", lap_note)

# Measured, not made: left out of a result's outputs token (matrix.store), so a job run again (--force) that
# made the same recording, frames, network or artifact leaves what stands on it fresh.
measured_keys("record", "wall_seconds")
measured_keys("frames", "decode_fps")
measured_keys("train", "seconds", "epoch_seconds")
measured_keys("prepare", "seconds")      # each fine-tune epoch's, in its "finetune" history
measured_keys("optimize", "seconds")
