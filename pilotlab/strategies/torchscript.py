"""`torchscript`: graph-optimised fp32 — traced, frozen and optimised for inference.

Why TorchScript rather than torch.compile: a compiled function cannot be saved, and AOTInductor
needs a C++ toolchain on every target; a frozen TorchScript file loads anywhere libtorch runs.
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.artifact import save_torchscript
from pilotlab.strategies.registry import StrategySource, register_strategy


@dataclass(frozen=True)
class TorchScriptConfig:
    version: int = 1


@register_strategy("torchscript", TorchScriptConfig)
def torchscript(config: TorchScriptConfig, source: StrategySource) -> dict:
    save_torchscript(source.load_model(), source.out / "model.ts", source.input_shape)
    source.write(source.meta(format="torchscript", file="model.ts", runtime="torch",
                             dtype="float32", extra={"frozen": True}))
    return {}
