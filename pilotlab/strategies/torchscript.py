"""`torchscript`: graph-optimised fp32 — traced, frozen and optimised for inference
(config: configs/torchscript.py).

Why TorchScript rather than torch.compile: a compiled function cannot be saved, and AOTInductor
needs a C++ toolchain on every target; a frozen TorchScript file loads anywhere libtorch runs.
"""
from __future__ import annotations

from pilotlab.strategies.configs.torchscript import TorchScriptConfig
from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.saving import save_torchscript


def torchscript(config: TorchScriptConfig, source: StrategySource) -> dict:
    save_torchscript(source.load_model(), source.out / "model.ts", source.input_shape)
    source.write(source.meta(format="torchscript", file="model.ts", runtime="torch",
                             dtype="float32", extra={"frozen": True}))
    return {}
