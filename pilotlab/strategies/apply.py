"""Applying a strategy: what its handler is given (`StrategySource`: the trained checkpoint, the
training frames, the target hardware, the folder to write into) and `apply_strategy`, which builds
the config, runs the handler and sums up the artifact. The run side of the registry
(pilotlab/strategies/registry.py): handlers and the optimize job import it, planning never does.
"""
from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from matrix.errors import MatrixError
from matrix.kinds import NotApplicable
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.errors import PilotlabError, clipped
from pilotlab.hardware import BUILTIN, HardwareProfile
from pilotlab.models import load_checkpoint
from pilotlab.models.imported import IMPORTED_ARCHS
from pilotlab.strategies.artifact import ArtifactMeta, artifact_size_gz_mb, artifact_size_mb, read_meta, write_meta
from pilotlab.strategies.registry import STRATEGIES, StrategyEntry, make_strategy_config

if TYPE_CHECKING:  # for the annotations only: a handler imports torch itself
    import torch
    from torch import nn


@dataclass
class StrategySource:
    """Everything a strategy may use: the trained checkpoint, calibration/fine-tuning frames, the
    hardware it targets and the (empty) folder to write the artifact into."""
    checkpoint_path: Path
    out: Path
    calibration_dirs: tuple[Path, ...] = ()
    hardware: HardwareProfile = BUILTIN["cpu"]
    strategy: str = ""               # the strategy being applied (set by apply_strategy)
    prepared: tuple[Path, dict] | None = None   # the prepare job's folder and figures (strategies/prepared.py)
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("pilotlab.strategies"))
    progress: Callable[..., None] = lambda *args, **kwargs: None

    def load_model(self) -> nn.Module:
        """A fresh copy of the trained network, in eval mode."""
        model, _ = load_checkpoint(self.checkpoint_path)
        return model

    @property
    def imported(self) -> str | None:
        """"network", "torchscript" or "onnx" for a model the user brought (pilotlab.models.imported),
        None for a built-in arch."""
        arch = self.checkpoint.get("arch")
        return arch if arch in IMPORTED_ARCHS else None

    @property
    def origin(self) -> str:
        """The model's source in words, for messages: "the ONNX graph nets/x.onnx"."""
        source = self.checkpoint.get("source") or {}
        what = {"network": "the network class", "torchscript": "the TorchScript model",
                "onnx": "the ONNX graph"}.get(self.imported, "the model")
        return f"{what} {source.get('file', '')}".strip()

    @cached_property
    def checkpoint(self) -> dict[str, Any]:
        _, payload = load_checkpoint(self.checkpoint_path)
        payload.pop("state_dict", None)
        return payload

    @property
    def labels(self) -> LabelRanges:
        if "labels" not in self.checkpoint:
            raise PilotlabError(f"{self.checkpoint_path}: the checkpoint has no 'labels' ranges; "
                                "retrain with this pilotlab (save_checkpoint(..., labels=ranges.as_dict()))")
        return LabelRanges.from_dict(self.checkpoint["labels"])

    @property
    def training_precision(self) -> str:
        """The precision the model was trained in, as its recipe asked (pilotlab.training; "auto" for a
        checkpoint that does not say)."""
        return (self.checkpoint.get("training") or {}).get("precision", "auto")

    @property
    def input_shape(self) -> tuple:
        config = self.checkpoint.get("config", {})
        channels = config.get("channels", 3) * int(config.get("frames", 1))  # temporal models stack frames
        return (None, channels, config.get("height", 66), config.get("width", 200))

    @property
    def frames(self) -> int:
        """Consecutive camera frames per input (C = 3 × frames)."""
        return max(1, self.input_shape[1] // 3)

    @cached_property
    def calibration(self) -> FrameSet:
        """The training frames, for calibration and fine-tuning."""
        if not self.calibration_dirs:
            raise PilotlabError("this strategy needs training frames (for calibration or fine-tuning): "
                                "give the optimize job a `calibration` dependency on the frames jobs")
        sets = [FrameSet.load(d) for d in self.calibration_dirs]
        return sets[0] if len(sets) == 1 else FrameSet.concat(sets)

    def calibration_batches(self, max_frames: int, batch_size: int = 32) -> Iterator[torch.Tensor]:
        """Up to `max_frames` frames spread evenly over the training set (every recording)."""
        data = self.calibration
        index = np.unique(np.linspace(0, len(data) - 1, min(max_frames, len(data))).astype(np.int64))
        for start in range(0, len(index), batch_size):
            yield data.inputs(index[start:start + batch_size], self.frames)

    def meta(self, *, format: str, file: str, runtime: str, dtype: str,
             device: str = "cpu", extra: dict | None = None) -> ArtifactMeta:
        """What artifact.json says of the artifact the applied strategy wrote."""
        entry = STRATEGIES.get(self.strategy)
        return ArtifactMeta(strategy=self.strategy, strategy_version=entry.version, format=format, file=file,
                            runtime=runtime, dtype=dtype, input_shape=self.input_shape,
                            arch=self.checkpoint["arch"], config=self.checkpoint.get("config", {}),
                            labels=self.checkpoint.get("labels", {}),
                            preprocess=self.checkpoint.get("preprocess", {}), device=device,
                            extra=extra or {})

    def write(self, meta: ArtifactMeta) -> None:
        write_meta(self.out, meta)


def apply_strategy(name: str, options: dict[str, Any] | None, source: StrategySource) -> dict[str, Any]:
    """Run strategy `name` on the checkpoint; returns its result (artifact summary + specifics)."""
    config = make_strategy_config(name, options)
    source.strategy = name
    source.out.mkdir(parents=True, exist_ok=True)
    specifics = run_handler(STRATEGIES.get(name), config, source)
    meta = read_meta(source.out)
    return {"strategy": name, "strategy_version": meta.strategy_version,
            "options": dataclasses.asdict(config), "format": meta.format, "runtime": meta.runtime,
            "dtype": meta.dtype, "device": meta.device, "file": meta.file,
            "size_mb": artifact_size_mb(source.out), "size_gz_mb": artifact_size_gz_mb(source.out), **specifics}


def run_handler(entry: StrategyEntry, config, source: StrategySource) -> dict[str, Any]:
    """The strategy's own figures. On a model the user brought, a strategy that cannot work on it is not
    applicable (an ONNX graph for a PyTorch strategy; a network it cannot trace or rewrite), never a crash."""
    check_takes(entry.name, source, entry.takes_onnx)
    entry.check_installed()
    return on_user_model(entry.name, source, lambda: entry.handler(config, source) or {}, entry.takes_onnx)


def check_takes(name: str, source: StrategySource, takes_onnx: bool = False) -> None:
    """NotApplicable for a user's ONNX graph where `name` works on a PyTorch network."""
    if source.imported == "onnx" and not takes_onnx:
        raise NotApplicable(f"{name} works on a PyTorch network, not on {source.origin} (strategies for ONNX "
                            "graphs: " + ", ".join(n for n, e in STRATEGIES.items() if e.takes_onnx) + ")")


def on_user_model(name: str, source: StrategySource, call: Callable[[], Any], takes_onnx: bool = False) -> Any:
    """`call()` (strategy or preparation `name` at work on `source`); on a model the user brought, an error
    is that it cannot work on that model: NotApplicable, with the first line of the error."""
    if source.imported is None:
        return call()
    try:
        return call()
    except (MatrixError, KeyboardInterrupt, MemoryError):
        raise
    except Exception as error:  # noqa: BLE001 — the user's network is outside what the strategy handles
        first = clipped(str(error).strip().splitlines()[0], 300) if str(error).strip() else ""
        hint = ""
        if source.imported == "torchscript":   # an ONNX strategy starts from the program's ONNX export
            hint = (" (its ONNX export, which this strategy starts from, failed)" if takes_onnx else
                    " (it rewrites nn.Module layers, which a TorchScript program does not expose; give `network:`, "
                    "the class, to run it)")
        raise NotApplicable(f"{name} cannot work on {source.origin}{hint}: {type(error).__name__}"
                            + (f": {first}" if first else "")) from error
