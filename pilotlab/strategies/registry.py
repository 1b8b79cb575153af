"""The strategy registry: name -> (frozen, versioned config dataclass, handler).

    @dataclass(frozen=True)
    class LocalPruneConfig:
        version: int = 1
        conv: float = 0.3

    @register_strategy("local_prune", LocalPruneConfig)   # the name, given once
    def local_prune(config: LocalPruneConfig, source: StrategySource) -> dict:
        model = source.load_model()          # a fresh copy of the trained checkpoint
        ...                                  # write the artifact into source.out
        source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime", dtype="fp32"))
        return {"sparsity": 0.4}             # strategy-specific results

`register_strategy(..., hardware_dependent=True)` says the artifact depends on the target hardware
(fp16, tensorrt): the planner then makes one optimize job per target device.

Options come from the recipe's `strategies:` section; an unknown option is an error naming the
strategy and its known options. Every handler starts from the checkpoint on disk, so no strategy
ever sees another one's changes. A strategy that cannot run on the target hardware raises
`matrix.NotApplicable(reason)`.

Planning imports every strategy module for its name and config, so a strategy module imports torch
(and onnxruntime, torchao...) inside the functions that use them, or from a helper module its
handler imports, never at its top: `pilotlab plan` stays quick
(tests/pilotlab/cli/test_light_imports.py).
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
from matrix.registry import Registry
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.errors import PilotlabError
from pilotlab.hardware import BUILTIN, HardwareProfile
from pilotlab.models import load_checkpoint
from pilotlab.specs.base import build_config
from pilotlab.strategies.artifact import ArtifactMeta, artifact_size_gz_mb, artifact_size_mb, read_meta, write_meta

if TYPE_CHECKING:
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
        from pilotlab.models.imported import IMPORTED_ARCHS
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


Handler = Callable[[Any, StrategySource], dict]


@dataclass(frozen=True)
class StrategyEntry:
    name: str
    config_cls: type
    handler: Handler
    module: str                      # the module that implements it (its code fingerprint)
    hardware_dependent: bool = False  # its artifact depends on the target device (one job per device)
    takes_onnx: bool = False         # it works on the ONNX graph, so it runs on a user's onnx: model too

    @property
    def version(self) -> int:
        return self.config_cls().version

    @property
    def options(self) -> list[str]:
        return [f.name for f in dataclasses.fields(self.config_cls) if f.name != "version"]



STRATEGIES: Registry[StrategyEntry] = Registry("strategy")


def register_strategy(name: str, config_cls: type, *, hardware_dependent: bool = False, takes_onnx: bool = False
                      ) -> Callable[[Handler], Handler]:
    if not (dataclasses.is_dataclass(config_cls) and config_cls.__dataclass_params__.frozen):
        raise TypeError(f"strategy {name!r}: its config must be a frozen dataclass")
    if "version" not in {f.name for f in dataclasses.fields(config_cls)}:
        raise TypeError(f"strategy {name!r}: its config needs a `version` field")

    def decorate(handler: Handler) -> Handler:
        STRATEGIES.add(name, StrategyEntry(name, config_cls, handler, handler.__module__, hardware_dependent,
                                           takes_onnx))
        return handler
    return decorate


def make_strategy_config(name: str, options: dict[str, Any] | None = None):
    """The strategy's config from recipe options; unknown options and wrong types are errors."""
    return build_config(STRATEGIES.get(name).config_cls, options, f"strategies.{name}")


def apply_strategy(name: str, options: dict[str, Any] | None, source: StrategySource) -> dict[str, Any]:
    """Run strategy `name` on the checkpoint; returns its result (artifact summary + specifics)."""
    config = make_strategy_config(name, options)
    source.strategy = name
    source.out.mkdir(parents=True, exist_ok=True)
    specifics = _run_handler(STRATEGIES.get(name), config, source)
    meta = read_meta(source.out)
    return {"strategy": name, "strategy_version": meta.strategy_version,
            "options": dataclasses.asdict(config), "format": meta.format, "runtime": meta.runtime,
            "dtype": meta.dtype, "device": meta.device, "file": meta.file,
            "size_mb": artifact_size_mb(source.out), "size_gz_mb": artifact_size_gz_mb(source.out), **specifics}


def _run_handler(entry: StrategyEntry, config, source: StrategySource) -> dict[str, Any]:
    """The strategy's result. On a model the user brought, a strategy that cannot work on it is not
    applicable (an ONNX graph for a PyTorch strategy; a network it cannot trace or rewrite), never a crash."""
    if source.imported == "onnx" and not entry.takes_onnx:
        raise NotApplicable(f"{entry.name} works on a PyTorch network, not on {source.origin} (strategies for ONNX "
                            "graphs: " + ", ".join(n for n, e in STRATEGIES.items() if e.takes_onnx) + ")")
    if source.imported is None:
        return entry.handler(config, source) or {}
    try:
        return entry.handler(config, source) or {}
    except (MatrixError, KeyboardInterrupt, MemoryError):
        raise
    except Exception as error:  # noqa: BLE001 — the user's network is outside what the strategy handles
        first = str(error).strip().splitlines()[0][:300] if str(error).strip() else ""
        hint = (" (it rewrites nn.Module layers, which a TorchScript program does not expose; give `network:`, "
                "the class, to run it)" if source.imported == "torchscript" else "")
        raise NotApplicable(f"{entry.name} cannot work on {source.origin}{hint}: {type(error).__name__}"
                            + (f": {first}" if first else "")) from error
