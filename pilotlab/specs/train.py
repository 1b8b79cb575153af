"""The `train` job: frames from one or more recordings -> a trained network checkpoint.

Its settings are the recipe's `models.<name>` entries (which add `data`, the dataset to train on).
"""
from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from matrix.fingerprint import module_closure
from matrix.kinds import register_kind
from pilotlab.models import MODELS
from pilotlab.specs.base import Spec, user_code_name
from pilotlab.specs.frames import PreprocessConfig

DEFAULT_ARCH = "pilotnet"
SOURCES = ("arch", "network", "torchscript", "onnx")   # where a model comes from: exactly one
# Presets: settings another tool trained with, one word away (docs/own-network.md).
PRESETS: dict[str, dict[str, Any]] = {
    # DeepLearningStudio's PyTorch PilotNet (and BehaviorMetrics' brain running it): rows 240:480 of a
    # 640x480 RGB image, cv2.resize to 200x66 (bilinear), ToTensor ([0, 1]); v min-max normalised over
    # [6.5, 24] and w over [-7.1, 7.1] (Formula1-FollowLine/pytorch/PilotNet/utils/processing.py).
    "dls": {"preprocess": {"crop_top": 0.5, "crop_bottom": 1.0, "width": 200, "height": 66,
                           "interpolation": "linear"},
            "labels": {"v": [6.5, 24.0], "w": [-7.1, 7.1]}},
}


Precision = Literal["auto", "fp32", "bf16"]   # of the training and fine-tunes: pilotlab.training


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
    """How a model is made: a built-in `arch`, the user's PyTorch class (`network`), or a whole model
    file (`torchscript`, `onnx`); paths as the recipe wrote them (their content is the job's inputs)."""
    arch: str | None = Field(None, description=f"a registered model (pilotnet, pilotnet_stacked, ...); the "
                                               f"default, {DEFAULT_ARCH}, when no other source is given")
    network: str | None = Field(None, description="the user's nn.Module class: file.py:Class or module:Class")
    torchscript: str | None = Field(None, min_length=1, description="a whole TorchScript model file (torch.jit.save)")
    onnx: str | None = Field(None, min_length=1, description="an ONNX model file")
    options: dict[str, Any] = Field({}, description="fields of the arch's config, e.g. {frames: 3}; with network: "
                                                   "the class's constructor keyword arguments")
    weights: str | None = Field(None, min_length=1, description="a state dict (.pth/.pt) to start from "
                                                                "(arch or network)")
    train: bool | None = Field(None, description="train (from the weights, if given); false: use the weights "
                                                 "or the model file as they are. Default: true for arch and "
                                                 "network, false for torchscript and onnx")
    preset: Literal["dls"] | None = Field(None, description="dls: DeepLearningStudio's preprocessing and label "
                                                            "ranges (explicit preprocess/labels win)")
    preprocess: PreprocessConfig | None = Field(None, description="crop and resize of the camera image (default: "
                                                                  "pilotlab's, the frames jobs')")
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
    precision: Precision = Field(
        "auto", description="bf16: mixed precision (bfloat16 forward pass, float32 weights and loss), ~2.4x "
                            "faster a step where the CPU has AVX512-BF16 or AMX; auto: bf16 there, else fp32. "
                            "The strategies' fine-tunes follow it (QAT's stay fp32)")

    @field_validator("network")
    @classmethod
    def _network_named(cls, network):
        return user_code_name(network)

    @field_validator("labels")
    @classmethod
    def _ranges(cls, labels):
        """{"v": [lo, hi], "w": [lo, hi]}, lo < hi: told when the recipe is planned, not by the training."""
        if labels == "auto":
            return labels
        if sorted(labels) != ["v", "w"]:
            raise ValueError(f"give the ranges of v and w, {{v: [lo, hi], w: [lo, hi]}}, or auto; got {sorted(labels)}")
        for name in ("v", "w"):
            lo_hi = labels[name]
            if len(lo_hi) != 2 or not all(math.isfinite(x) for x in lo_hi) or not lo_hi[0] < lo_hi[1]:
                raise ValueError(f"{name}: {lo_hi} is not a range [lo, hi] of finite numbers with lo < hi")
        return labels

    @model_validator(mode="before")
    @classmethod
    def _one_source_and_preset(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        given = [name for name in SOURCES if data.get(name) is not None]
        if len(given) > 1:
            raise ValueError(f"give one of {', '.join(SOURCES)}, not {' and '.join(given)}")
        data = dict(data) if given else {**data, "arch": DEFAULT_ARCH}
        for key, value in PRESETS.get(data.get("preset"), {}).items():
            data.setdefault(key, value)
        return data

    @model_validator(mode="after")
    def _training_fits_the_source(self):
        if self.train and self.source in ("torchscript", "onnx"):
            raise ValueError(f"train: true: {self.source} models are used as they are; give `network:` (the PyTorch "
                             "class) to train it")
        if self.train is False and self.source in ("arch", "network") and self.weights is None:
            raise ValueError("train: false needs `weights:` (a state dict to use as it is)")
        if self.weights is not None and self.source not in ("arch", "network"):
            raise ValueError(f"weights: {self.source} files hold their weights; weights go with arch or network")
        if not self.trains and self.labels == "auto":
            raise ValueError("labels: a model used as it is needs the label ranges it was trained with: give "
                             "labels: {v: [lo, hi], w: [lo, hi]} or a preset (preset: dls)")
        if self.source in ("torchscript", "onnx") and self.options:
            raise ValueError(f"options: {self.source} models take no constructor options")
        return self

    @property
    def source(self) -> str:
        """Where the model comes from: "arch", "network", "torchscript" or "onnx"."""
        return next(name for name in SOURCES if getattr(self, name) is not None)

    @property
    def trains(self) -> bool:
        return self.train if self.train is not None else self.source in ("arch", "network")


def arch_modules(params) -> list[str]:
    """The modules that define the arch: its network's, and the model modules that one imports (the
    networks it builds on), read from the source without importing them."""
    if any(params.get(name) for name in SOURCES[1:]):   # the user's model: its files are the job's inputs
        return ["pilotlab.models.user"]
    entry = MODELS.get(params.get("arch") or DEFAULT_ARCH)
    return module_closure(entry.network_module, "pilotlab.models", exclude=["pilotlab.models.registry"])


# Training runs alone, on every core: beside another job torch's threads spin against it, and on one
# core of two the quickstart's training took 58 s instead of ~30 (what could run beside it, the reference
# laps, runs beside the fine-tunes later).
def trains_alone(params) -> bool:
    """A training has the host to itself (its threads use every core); a model used as it is (train: false,
    a TorchScript or ONNX file) is only loaded and checked: it runs beside other jobs."""
    return TrainSpec.model_validate(params).trains


register_kind("train", "pilotlab.jobs.train:run_train", params=TrainSpec, code_for=arch_modules,
              exclusive_for=trains_alone)
