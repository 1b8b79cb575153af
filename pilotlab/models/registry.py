"""The model registry and checkpoints.

A model is a frozen config dataclass registered with the `nn.Module` class it configures:

    @register_model("pilotnet", network="pilotlab.models.pilotnet.PilotNet")
    @dataclass(frozen=True)
    class PilotNetConfig: ...          # in configs.py

    class PilotNet(nn.Module):         # in pilotnet.py
        def __init__(self, config: PilotNetConfig): ...

The network is named, not imported: planning validates a recipe's models without torch, and the
network's module is imported when a model is first built.

Every model takes a float32 batch `[N, C, H, W]` (RGB in [0, 1], C = 3 × frames) and returns
normalised labels `[N, 2]` (v, w). A checkpoint embeds the model's arch and config, so it can be
rebuilt without the recipe, plus whatever the data pipeline needs at drive time.
"""
from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from matrix.registry import Registry
from pilotlab.errors import PilotlabError
from pilotlab.specs.base import build_config

if TYPE_CHECKING:
    from torch import nn

CHECKPOINT_FORMAT = "pilotlab-checkpoint/1"


@dataclass(frozen=True)
class ModelEntry:
    name: str
    config_cls: type
    network: str                     # "package.module.Class" of the nn.Module

    @property
    def network_module(self) -> str:
        return self.network.rpartition(".")[0]

    @property
    def module_cls(self) -> type[nn.Module]:
        module, _, cls = self.network.rpartition(".")
        return getattr(importlib.import_module(module), cls)


MODELS: Registry[ModelEntry] = Registry("model")


def register_model(name: str, *, network: str):
    """Register the decorated config dataclass as model `name`, built by the class `network` names."""
    def decorate(config_cls: type) -> type:
        MODELS.add(name, ModelEntry(name, config_cls, network))
        return config_cls
    return decorate


def make_config(arch: str, params: dict[str, Any] | None = None):
    """The arch's config dataclass filled from `params`; unknown fields are an error."""
    return build_config(MODELS.get(arch).config_cls, params, f"model {arch!r}")


def input_frames(config) -> int:
    """Consecutive frames a model takes per input: its config's `frames` field, else 1."""
    return int(getattr(config, "frames", 1))


def build_model(arch: str, config=None) -> nn.Module:
    entry = MODELS.get(arch)
    return entry.module_cls(config if config is not None else entry.config_cls())


def save_checkpoint(path: Path, model: nn.Module, arch: str, config, **extra: Any) -> None:
    """Write a checkpoint with the arch, its config and `extra` (normalisation, preprocessing, history)."""
    import torch
    payload = {"format": CHECKPOINT_FORMAT, "arch": arch, "config": dataclasses.asdict(config),
               "state_dict": model.state_dict(), **extra}
    tmp = Path(path).with_suffix(".tmp")
    torch.save(payload, tmp)
    tmp.replace(path)


def load_checkpoint(path: Path) -> tuple[nn.Module, dict[str, Any]]:
    """(model in eval mode, the whole checkpoint dict)."""
    import torch
    try:
        payload = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as error:  # torch raises many types for a bad file
        raise PilotlabError(f"{path}: not a readable checkpoint ({error})") from None
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise PilotlabError(f"{path}: not a pilotlab checkpoint (expected format {CHECKPOINT_FORMAT})")
    model = build_model(payload["arch"], make_config(payload["arch"], payload["config"]))
    model.load_state_dict(payload["state_dict"])
    return model.eval(), payload
