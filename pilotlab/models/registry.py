"""The model registry and checkpoints.

A model is an `nn.Module` class registered with its frozen config dataclass:

    @register_model("pilotnet", PilotNetConfig)
    class PilotNet(nn.Module):
        def __init__(self, config: PilotNetConfig): ...

Every model takes a float32 batch `[N, C, H, W]` (RGB in [0, 1], C = 3 × frames) and returns
normalised labels `[N, 2]` (v, w). A checkpoint embeds the model's arch and config, so it can be
rebuilt without the recipe, plus whatever the data pipeline needs at drive time.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch import nn

from matrix.registry import Registry
from pilotlab.errors import PilotlabError

CHECKPOINT_FORMAT = "pilotlab-checkpoint/1"


@dataclass(frozen=True)
class ModelEntry:
    name: str
    config_cls: type
    module_cls: type[nn.Module]


MODELS: Registry[ModelEntry] = Registry("model")


def register_model(name: str, config_cls: type):
    def decorate(module_cls: type[nn.Module]) -> type[nn.Module]:
        MODELS.add(name, ModelEntry(name, config_cls, module_cls))
        return module_cls
    return decorate


def make_config(arch: str, params: dict[str, Any] | None = None):
    """The arch's config dataclass filled from `params`; unknown fields are an error."""
    entry = MODELS.get(arch)
    fields = {f.name for f in dataclasses.fields(entry.config_cls)}
    unknown = sorted(set(params or {}) - fields)
    if unknown:
        raise PilotlabError(f"model {arch!r} has no option(s) {', '.join(unknown)}; "
                            f"its options are: {', '.join(sorted(fields))}")
    return entry.config_cls(**(params or {}))


def input_frames(config) -> int:
    """Consecutive frames a model takes per input: its config's `frames` field, else 1."""
    return int(getattr(config, "frames", 1))


def build_model(arch: str, config=None) -> nn.Module:
    entry = MODELS.get(arch)
    return entry.module_cls(config if config is not None else entry.config_cls())


def save_checkpoint(path: Path, model: nn.Module, arch: str, config, **extra: Any) -> None:
    """Write a checkpoint with the arch, its config and `extra` (normalisation, preprocessing, history)."""
    payload = {"format": CHECKPOINT_FORMAT, "arch": arch, "config": dataclasses.asdict(config),
               "state_dict": model.state_dict(), **extra}
    tmp = Path(path).with_suffix(".tmp")
    torch.save(payload, tmp)
    tmp.replace(path)


def load_checkpoint(path: Path) -> tuple[nn.Module, dict[str, Any]]:
    """(model in eval mode, the whole checkpoint dict)."""
    try:
        payload = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as error:  # torch raises many types for a bad file
        raise PilotlabError(f"{path}: not a readable checkpoint ({error})") from None
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise PilotlabError(f"{path}: not a pilotlab checkpoint (expected format {CHECKPOINT_FORMAT})")
    model = build_model(payload["arch"], make_config(payload["arch"], payload["config"]))
    model.load_state_dict(payload["state_dict"])
    return model.eval(), payload
