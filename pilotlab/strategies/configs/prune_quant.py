"""The config of `prune_quant` (its handler: pilotlab/strategies/prune_quant.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.configs.checks import check_fraction
from pilotlab.strategies.configs.pt2e import QatConfig
from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class PruneQuantConfig:
    version: int = 1
    conv: float = 0.3
    linear: float = 0.5
    calibration_frames: int = 256    # observed before quantization-aware fine-tuning
    finetune_epochs: int = 2         # after pruning, and again with fake quantization
    qat_epochs: int | None = None    # with fake quantization, if not finetune_epochs
    lr: float = 1e-4
    batch_size: int = 64

    def __post_init__(self) -> None:
        check_fraction("conv", self.conv)
        check_fraction("linear", self.linear)

    @property
    def quantization_aware(self) -> QatConfig:
        """The settings of its quantization-aware fine-tune."""
        epochs = self.finetune_epochs if self.qat_epochs is None else self.qat_epochs
        return QatConfig(calibration_frames=self.calibration_frames, finetune_epochs=epochs, lr=self.lr,
                         batch_size=self.batch_size)


# local_prune's network (one shared prepare job when conv, linear and the fine-tune's options agree)
register_strategy("prune_quant", PruneQuantConfig, "pilotlab.strategies.prune_quant:prune_quant",
                  prepared_by="l1_pruning")
