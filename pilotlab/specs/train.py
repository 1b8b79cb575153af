"""The `train` job: frames from one or more recordings -> a trained network checkpoint.

Its settings are the recipe's `models.<name>` entries (which add `data`, the dataset to train on).
"""
from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from matrix.fingerprint import module_closure
from matrix.kinds import register_kind
from pilotlab.models import MODELS
from pilotlab.specs.base import Spec


class AugmentConfig(Spec):
    """Training-time augmentation (pilotlab.data.augment)."""
    version: int = 1
    flip: bool = Field(False, description="mirror images, negating w")
    oversample_curves: float = Field(0.0, ge=0, le=100, description="extra weight of curve frames (0: none)")
    curve_threshold: float = Field(0.3, ge=0, le=1)
    color_jitter: float = Field(0.0, ge=0, le=1)
    blur: float = Field(0.0, ge=0, le=1)
    affine: float = Field(0.0, ge=0, le=1)

    @property
    def transforms_images(self) -> bool:
        return self.flip or self.color_jitter > 0 or self.blur > 0 or self.affine > 0


class TrainSpec(Spec):
    arch: str = Field("pilotnet", description="a registered model (pilotnet, pilotnet_stacked, ...)")
    options: dict[str, Any] = Field({}, description="fields of the arch's config, e.g. {frames: 3}")
    epochs: int = Field(20, ge=1, le=100_000)
    batch_size: int = Field(64, ge=1, le=1_000_000)
    lr: float = Field(1e-3, gt=0, le=100)
    patience: int | None = Field(5, ge=1, description="early stopping: epochs without a better validation loss")
    val_fraction: float = Field(0.2, ge=0, lt=1, description="share of frames held out for validation")
    val_by: Literal["auto", "recording", "block"] = Field(
        "auto", description="recording: whole recordings held out; block: the last part of each; "
                            "auto: by recording with 3 or more recordings, else by block")
    labels: Literal["auto"] | dict[str, list[float]] = Field(
        "auto", description='normalisation ranges {"v": [lo, hi], "w": [lo, hi]}, or "auto"')
    seed: int = Field(0, ge=0, lt=2**32)
    augment: AugmentConfig = AugmentConfig()


def arch_modules(params) -> list[str]:
    """The modules that define the arch: its network's, and the model modules that one imports (the
    networks it builds on), read from the source without importing them."""
    entry = MODELS.get(params.get("arch", TrainSpec.model_fields["arch"].default))
    return module_closure(entry.network_module, "pilotlab.models", exclude=["pilotlab.models.registry"])


register_kind("train", "pilotlab.jobs.train:run_train", params=TrainSpec, code_for=arch_modules)
