"""The configs of the TF-MOT rows on LiteRT (their handlers: pilotlab/strategies/mot.py). They
need the optional `edge` extra: without it they are "not applicable" and their handlers are never
imported."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.configs.checks import check_clusters, check_distill, check_fraction
from pilotlab.strategies.edge import EXTRA, LITERT_CONVERTER
from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class PruneLiteRTConfig:
    version: int = 1
    sparsity: float = 0.5            # fraction of each conv/linear layer's weights set to zero
    finetune_epochs: int = 2         # fine-tuning with the mask held
    lr: float = 1e-4
    batch_size: int = 64
    distill: float = 0.0             # knowledge distillation: weight of the trained baseline's outputs

    def __post_init__(self) -> None:
        check_fraction("sparsity", self.sparsity)
        check_distill(self.distill)


@dataclass(frozen=True)
class QatLiteRTConfig:
    version: int = 1
    qat_epochs: int = 2              # fine-tuning with fake quantization
    lr: float = 1e-4
    batch_size: int = 64
    calibration_frames: int = 512    # ranges observed before QAT; the conversion's representative dataset
    distill: float = 0.0             # knowledge distillation: weight of the trained baseline's outputs

    def __post_init__(self) -> None:
        check_distill(self.distill)


@dataclass(frozen=True)
class PruneLiteRTInt8Config(PruneLiteRTConfig):
    calibration_frames: int = 512    # the representative dataset of the int8 conversion


@dataclass(frozen=True)
class PqatConfig(PruneLiteRTInt8Config):
    qat_epochs: int = 2              # QAT after the pruning fine-tune, with the mask held


@dataclass(frozen=True)
class CqatConfig(QatLiteRTConfig):
    clusters: int = 16               # shared values per layer (TF-MOT's example uses 16)
    iterations: int = 30             # k-means (Lloyd) iterations
    finetune_epochs: int = 2         # fine-tuning the centroids, before QAT

    def __post_init__(self) -> None:
        super().__post_init__()
        check_clusters(self.clusters)


@dataclass(frozen=True)
class PcqatConfig(PqatConfig):
    clusters: int = 16               # shared values per layer, zero one of them
    iterations: int = 30
    cluster_epochs: int = 2          # fine-tuning the centroids, between pruning and QAT

    def __post_init__(self) -> None:
        super().__post_init__()
        check_clusters(self.clusters)


_HANDLERS = "pilotlab.strategies.mot"
register_strategy("prune_litert", PruneLiteRTConfig, f"{_HANDLERS}:prune_litert",
                  requires=LITERT_CONVERTER, extra=EXTRA, prepared_by="magnitude_pruning")
register_strategy("prune_litert_int8", PruneLiteRTInt8Config, f"{_HANDLERS}:prune_litert_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA, prepared_by="magnitude_pruning")
register_strategy("qat_litert_int8", QatLiteRTConfig, f"{_HANDLERS}:qat_litert_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA)
register_strategy("pqat_litert_int8", PqatConfig, f"{_HANDLERS}:pqat_litert_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA, prepared_by="magnitude_pruning")
register_strategy("cqat_litert_int8", CqatConfig, f"{_HANDLERS}:cqat_litert_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA)
register_strategy("pcqat_litert_int8", PcqatConfig, f"{_HANDLERS}:pcqat_litert_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA, prepared_by="magnitude_pruning")
