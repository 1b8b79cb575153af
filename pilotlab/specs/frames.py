"""The `frames` job: one recording (a bag or a dataset folder) -> preprocessed frames in the store.

Where the recording comes from (exactly one): `inputs["bag"]` (a user's bag or DeepLearningStudio
folder, content in the key), `deps["bag"]` (a record job) or the `path` param (jobs built by hand).
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from matrix.kinds import register_kind
from pilotlab.specs.base import Spec

INTERPOLATIONS = ("fast_area", "area", "linear")


class PreprocessConfig(Spec):
    """Rows [crop_top, crop_bottom) of the image (fractions of its height) resized to width×height,
    as DeepLearningStudio's PilotNet (which keeps rows 240:480 of a 640×480 image)."""
    version: int = 1
    crop_top: float = Field(0.5, ge=0, le=1)
    crop_bottom: float = Field(1.0, ge=0, le=1)
    width: int = Field(200, ge=1, le=4096)
    height: int = Field(66, ge=1, le=4096)
    interpolation: Literal["fast_area", "area", "linear"] = "fast_area"   # see pilotlab.data.preprocess.resize

    @model_validator(mode="after")
    def _rows_in_order(self):
        if not self.crop_top < self.crop_bottom:
            raise ValueError(f"preprocess crop_top={self.crop_top}, crop_bottom={self.crop_bottom}: need "
                             "0 <= crop_top < crop_bottom <= 1 (fractions of the image height)")
        return self

    @classmethod
    def from_params(cls, params) -> PreprocessConfig:
        """The config from the matching keys of `params` (other keys are ignored)."""
        return cls(**{k: params[k] for k in cls.model_fields if k in params and k != "version"})

    def rows(self, image_height: int) -> slice:
        top, bottom = round(self.crop_top * image_height), round(self.crop_bottom * image_height)
        return slice(top, max(bottom, top + 1))


class FramesSpec(PreprocessConfig):
    image_topic: str | None = Field(None, description="default: /F1ROS/cameraL/image_raw, else its /compressed")
    command_topic: str | None = Field(None, description="default: the record job's, else /F1ROS/cmd_vel")
    label: str | None = Field(None, description="a name for the recording (logs and results)")
    path: str | None = Field(None, description="the recording, for jobs built by hand (not hashed: prefer inputs)")


register_kind("frames", "pilotlab.jobs.frames:run_frames", params=FramesSpec)
