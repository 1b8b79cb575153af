"""Configs of the models a user brings (recipe `models:` with `network:`, `torchscript:` or `onnx:`).

A checkpoint of such a model is plain data, like any pilotlab checkpoint (torch.load with
weights_only=True reads it): the config says how to rebuild the network and the state dict holds
its tensors.

- "network": the user's nn.Module class, rebuilt by importing `network` (an absolute file.py:Class,
  or module:Class) and calling it with `options`; `source_hash` is the sha256 of its source
  (pilotlab.usercode.source_hash) when the checkpoint was written. The class is never pickled.
- "torchscript" / "onnx": the model file's bytes are the state dict's `program` (a uint8 tensor),
  so the checkpoint needs no file beside it; `sha256` is that file's.

The networks themselves (and torch) are in pilotlab.models.user, imported when a model is built.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pilotlab.models.registry import register_model

IMPORTED_ARCHS = ("network", "torchscript", "onnx")   # checkpoint archs of user models, never a recipe's arch


@register_model("network", network="pilotlab.models.user.build_network")
@dataclass(frozen=True)
class NetworkConfig:
    version: int = 1
    network: str = ""                # absolute file.py:Class (or module:Class) of the nn.Module
    options: dict[str, Any] = field(default_factory=dict)   # the constructor's keyword arguments
    source_hash: str = ""            # sha256 of the class's source when trained
    channels: int = 3                # the input it takes: [N, channels, height, width]
    height: int = 66
    width: int = 200


@register_model("torchscript", network="pilotlab.models.user.TorchScriptModel")
@dataclass(frozen=True)
class TorchScriptConfig:
    version: int = 1
    file: str = ""                   # where it was imported from (for people; the bytes are in the state dict)
    sha256: str = ""
    channels: int = 3
    height: int = 66
    width: int = 200


@register_model("onnx", network="pilotlab.models.user.OnnxModel")
@dataclass(frozen=True)
class OnnxConfig(TorchScriptConfig):
    pass
