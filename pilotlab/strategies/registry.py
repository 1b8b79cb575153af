"""The strategy registry: name -> (frozen, versioned config dataclass, handler named by string).

A strategy is two modules, as a job kind is (docs/CONVENTIONS.md): its config, which planning
imports for the strategy's name and options, and its handler, imported only when the strategy is
applied:

    # pilotlab/strategies/configs/prune.py: imported to plan, so it imports nothing heavy
    @dataclass(frozen=True)
    class LocalPruneConfig:
        version: int = 1             # bump it when the handler's output changes for the same options
        conv: float = 0.3

    register_strategy("local_prune", LocalPruneConfig, "pilotlab.strategies.prune:local_prune")

    # pilotlab/strategies/prune.py: imported by `apply_strategy` only, so torch at its top
    import torch

    def local_prune(config: LocalPruneConfig, source: StrategySource) -> dict:
        model = source.load_model()          # a fresh copy of the trained checkpoint
        ...                                  # write the artifact into source.out
        source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime", dtype="fp32"))
        return {"sparsity": 0.4}             # strategy-specific results

`hardware_dependent=True` says the artifact depends on the target hardware (fp16, tensorrt): the
planner then makes one optimize job per target device. `takes_onnx=True` says the handler works on
the ONNX graph, so it also runs on a user's `onnx:` model. `requires=` names the optional packages
the handler needs (found without importing them) and `extra=` the pip extra that installs them:
where one is missing the strategy is "not applicable: it needs X, not installed here (pip install -e
'.[extra]')" and its handler module, which imports them at its top, is never imported.

Options come from the recipe's `strategies:` section; an unknown option is an error naming the
strategy and its known options. Every handler starts from the checkpoint on disk, so no strategy
ever sees another one's changes. A strategy that cannot run on the target hardware raises
`matrix.NotApplicable(reason)`.

The code of an optimize job is its strategy's handler module and config module with what they
import within pilotlab (`pilotlab.specs.optimize`), so editing one strategy reruns only its jobs.
Planning imports every config module and no handler: `pilotlab plan` stays quick
(tests/pilotlab/cli/test_light_imports.py).
"""
from __future__ import annotations

import dataclasses
import importlib
import importlib.util
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
from pilotlab.models.imported import IMPORTED_ARCHS
from pilotlab.specs.base import build_config
from pilotlab.strategies.artifact import ArtifactMeta, artifact_size_gz_mb, artifact_size_mb, read_meta, write_meta

if TYPE_CHECKING:  # for the annotations only: planning imports this module
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


@dataclass(frozen=True, eq=False)
class StrategyEntry:
    name: str
    config_cls: type
    target: str | Handler            # "package.module:function", imported when the strategy is applied
    hardware_dependent: bool = False  # its artifact depends on the target device (one job per device)
    takes_onnx: bool = False         # it works on the ONNX graph, so it runs on a user's onnx: model too
    requires: tuple[str, ...] = ()   # optional packages its handler imports (checked before it is imported)
    extra: str = ""                  # the pip extra that installs them

    @property
    def module(self) -> str:
        """The handler's module."""
        return self.target.partition(":")[0] if isinstance(self.target, str) else self.target.__module__

    @property
    def modules(self) -> tuple[str, ...]:
        """The modules that implement it, the roots of its code fingerprint: the handler's and the config's."""
        return tuple(dict.fromkeys((self.module, self.config_cls.__module__)))

    @cached_property
    def handler(self) -> Handler:
        if not isinstance(self.target, str):
            return self.target
        module, _, function = self.target.partition(":")
        return getattr(importlib.import_module(module), function)

    @property
    def version(self) -> int:
        return self.config_cls().version

    @property
    def options(self) -> list[str]:
        return [f.name for f in dataclasses.fields(self.config_cls) if f.name != "version"]

    def check_installed(self) -> None:
        """NotApplicable unless every package the handler needs is installed here (found without
        importing it: its handler module imports them at its top, and is then never imported)."""
        if absent := [name for name in self.requires if importlib.util.find_spec(name) is None]:
            install = f" (pip install -e '.[{self.extra}]')" if self.extra else ""
            raise NotApplicable(f"{self.name} needs {', '.join(absent)}, not installed here{install}")

    def run(self, config, source: StrategySource) -> dict[str, Any]:
        """The strategy's result. On a model the user brought, a strategy that cannot work on it is not
        applicable (an ONNX graph for a PyTorch strategy; a network it cannot trace or rewrite), never a crash."""
        if source.imported == "onnx" and not self.takes_onnx:
            raise NotApplicable(f"{self.name} works on a PyTorch network, not on {source.origin} (strategies for ONNX "
                                "graphs: " + ", ".join(n for n, e in STRATEGIES.items() if e.takes_onnx) + ")")
        self.check_installed()
        handler = self.handler
        if source.imported is None:
            return handler(config, source) or {}
        try:
            return handler(config, source) or {}
        except (MatrixError, KeyboardInterrupt, MemoryError):
            raise
        except Exception as error:  # noqa: BLE001 — the user's network is outside what the strategy handles
            first = str(error).strip().splitlines()[0][:300] if str(error).strip() else ""
            hint = (" (it rewrites nn.Module layers, which a TorchScript program does not expose; give `network:`, "
                    "the class, to run it)" if source.imported == "torchscript" else "")
            raise NotApplicable(f"{self.name} cannot work on {source.origin}{hint}: {type(error).__name__}"
                                + (f": {first}" if first else "")) from error


STRATEGIES: Registry[StrategyEntry] = Registry("strategy")


def register_strategy(name: str, config_cls: type, handler: str | Handler, *, hardware_dependent: bool = False,
                      takes_onnx: bool = False, requires: tuple[str, ...] = (), extra: str = "") -> StrategyEntry:
    """Register strategy `name`: its config class and its handler, "package.module:function" (or the
    function itself)."""
    if not (dataclasses.is_dataclass(config_cls) and config_cls.__dataclass_params__.frozen):
        raise TypeError(f"strategy {name!r}: its config must be a frozen dataclass")
    if "version" not in {f.name for f in dataclasses.fields(config_cls)}:
        raise TypeError(f"strategy {name!r}: its config needs a `version` field")
    if isinstance(handler, str) and not all(handler.partition(":")[::2]):
        raise TypeError(f"strategy {name!r}: its handler {handler!r} is not \"package.module:function\"")
    return STRATEGIES.add(name, StrategyEntry(name, config_cls, handler, hardware_dependent, takes_onnx,
                                              tuple(requires), extra))


def make_strategy_config(name: str, options: dict[str, Any] | None = None):
    """The strategy's config from recipe options; unknown options and wrong types are errors."""
    return build_config(STRATEGIES.get(name).config_cls, options, f"strategies.{name}")


def apply_strategy(name: str, options: dict[str, Any] | None, source: StrategySource) -> dict[str, Any]:
    """Run strategy `name` on the checkpoint; returns its result (artifact summary + specifics)."""
    config = make_strategy_config(name, options)
    source.strategy = name
    source.out.mkdir(parents=True, exist_ok=True)
    specifics = STRATEGIES.get(name).run(config, source)
    meta = read_meta(source.out)
    return {"strategy": name, "strategy_version": meta.strategy_version,
            "options": dataclasses.asdict(config), "format": meta.format, "runtime": meta.runtime,
            "dtype": meta.dtype, "device": meta.device, "file": meta.file,
            "size_mb": artifact_size_mb(source.out), "size_gz_mb": artifact_size_gz_mb(source.out), **specifics}
