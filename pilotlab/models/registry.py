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
from pilotlab.errors import PilotlabError, library_message
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
    payload = plain_data({"format": CHECKPOINT_FORMAT, "arch": arch, "config": dataclasses.asdict(config),
                          "state_dict": model.state_dict(), **extra}, "checkpoint")
    tmp = Path(path).with_suffix(".tmp")
    torch.save(payload, tmp)
    tmp.replace(path)


def plain_data(value: Any, where: str) -> Any:
    """`value` with numpy scalars made Python numbers and tuples lists; anything but dicts, lists,
    str, numbers, bool, None and tensors is an error. A checkpoint holds only this, so that
    `torch.load(weights_only=True)` reads it and never runs code from the file."""
    import torch
    if value is None or type(value) in (str, bool, int, float) or isinstance(value, torch.Tensor):
        return value
    if isinstance(value, dict):
        return {k: plain_data(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain_data(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if type(value).__module__ == "numpy" and getattr(value, "shape", None) == ():
        return value.item()          # a numpy scalar (np.float64 is also a float: checked here)
    raise PilotlabError(f"{where}: a {type(value).__name__} cannot go into a checkpoint (plain data only)")


def load_checkpoint(path: Path) -> tuple[nn.Module, dict[str, Any]]:
    """(model in eval mode, the whole checkpoint dict).

    weights_only=True: a checkpoint is plain data (tensors, dicts, lists, numbers, strings); a file
    holding any other Python object (which unpickling would construct, running its code) is refused."""
    import pickle

    import torch
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as error:
        first = next((line for line in str(error).splitlines() if "Unsupported global" in line), "")
        raise PilotlabError(f"{path}: refused: the file holds Python objects, not only plain data "
                            f"({first.strip() or 'weights_only load failed'}); a pilotlab checkpoint never does, "
                            "so do not load it unless you trust its origin") from None
    except Exception as error:  # torch raises many types for a bad file
        first = library_message(error, 200)
        raise PilotlabError(f"{path}: not a readable checkpoint ({type(error).__name__}: {first})") from None
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise PilotlabError(f"{path}: not a pilotlab checkpoint (expected format {CHECKPOINT_FORMAT})")
    try:
        model = build_model(payload["arch"], make_config(payload["arch"], payload["config"]))
        model.load_state_dict(payload["state_dict"])
    except (KeyError, TypeError, ValueError, RuntimeError) as error:
        first = library_message(error, 200)
        raise PilotlabError(f"{path}: a damaged pilotlab checkpoint ({type(error).__name__}: {first})") from None
    return model.eval(), payload
