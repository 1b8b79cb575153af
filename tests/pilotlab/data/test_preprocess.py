"""Preprocessing: crop + resize, the network input, and the drive-time preprocessor."""
import cv2
import numpy as np
import pydantic
import pytest
import torch

from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.data.preprocess import DrivePreprocessor, PreprocessConfig, preprocess, to_input
from pilotlab.errors import PilotlabError
from tests.pilotlab.data.bagfiles import images


def test_crops_the_lower_half_and_resizes_to_200x66():
    camera = images(1, 480, 640, seed=3)[0]
    area = cv2.resize(camera[240:480], (200, 66), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(preprocess(camera, PreprocessConfig(interpolation="area")), area)
    frame = preprocess(camera, PreprocessConfig())
    assert frame.shape == (66, 200, 3) and frame.dtype == np.uint8
    halved = cv2.resize(camera[240:480], (320, 120), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(frame, cv2.resize(halved, (200, 66), interpolation=cv2.INTER_LINEAR))
    assert np.abs(frame.astype(int) - area).mean() < 1.0


def test_fast_area_keeps_a_thin_line_wherever_it_is_and_linear_does_not():
    def faintest_line(mode):
        reds = []
        for column in range(300, 316):
            camera = np.full((480, 640, 3), 100, np.uint8)
            camera[:, column:column + 2] = (255, 0, 0)              # a 2-pixel red line
            reds.append(int(preprocess(camera, PreprocessConfig(interpolation=mode))[..., 0].max()))
        return min(reds)
    assert faintest_line("area") > 140 and faintest_line("fast_area") > 140 and faintest_line("linear") == 100


def test_crop_and_interpolation_are_configurable():
    camera = images(1, 480, 640)[0]
    config = PreprocessConfig(crop_top=0.25, crop_bottom=0.75, width=100, height=40, interpolation="linear")
    np.testing.assert_array_equal(preprocess(camera, config), cv2.resize(camera[120:360], (100, 40)))


def test_the_upper_half_does_not_matter():
    camera = images(1, 480, 640)[0]
    other = camera.copy()
    other[:240] = 0
    np.testing.assert_array_equal(preprocess(camera, PreprocessConfig()), preprocess(other, PreprocessConfig()))


@pytest.mark.parametrize("fields, problem", [
    ({"crop_top": 0.6, "crop_bottom": 0.5}, "need 0 <= crop_top < crop_bottom <= 1"),
    ({"width": 0}, "width\n  Input should be greater than or equal to 1"),
    ({"interpolation": "cubic"}, "Input should be 'fast_area', 'area' or 'linear'"),
])
def test_bad_settings_are_refused(fields, problem):
    with pytest.raises(pydantic.ValidationError, match=problem):
        PreprocessConfig(**fields)


def test_unknown_encoding_is_refused():
    with pytest.raises(PilotlabError, match="image encoding 'rgba16' is not supported"):
        preprocess(images(1)[0], PreprocessConfig(), "rgba16")


def test_to_input_is_float_rgb_in_0_1_channels_first_oldest_first():
    frames = np.stack(images(2, 66, 200))
    single = to_input(frames)
    assert single.shape == (2, 3, 66, 200) and single.dtype == torch.float32
    assert torch.equal(single[1, 0], torch.from_numpy(frames[1, :, :, 0]).float() / 255)
    stacked = to_input(frames[None])
    assert stacked.shape == (1, 6, 66, 200)
    assert torch.equal(stacked[0, 3:], single[1])


def test_drive_preprocessor_gives_what_training_saw():
    camera = images(5, 480, 640)
    config = PreprocessConfig()
    frames = np.stack([preprocess(c, config) for c in camera])
    data = FrameSet(frames, np.zeros((5, 2), np.float32), np.zeros(5, np.int32))
    ranges = LabelRanges((0.0, 10.0), (-2.0, 2.0))
    checkpoint = {"preprocess": {**config.as_dict(), "frames": 3}, "labels": ranges.as_dict()}
    live = DrivePreprocessor.from_checkpoint(checkpoint)
    for i, image in enumerate(camera):
        assert torch.equal(live(image), data.inputs(np.array([i]), frames=3))
    assert live.commands(torch.tensor([[0.5, 0.25]])) == pytest.approx((5.0, -1.0))
    live.reset()
    assert torch.equal(live(camera[4]), data.inputs(np.array([4, 4, 4]), frames=1).reshape(1, 9, 66, 200))


def test_drive_preprocessor_needs_label_ranges():
    with pytest.raises(PilotlabError, match="checkpoint has no 'labels' ranges"):
        DrivePreprocessor.from_checkpoint({"preprocess": PreprocessConfig().as_dict()})


def test_drive_preprocessor_from_an_optimized_artifacts_settings():
    ranges = {"v": [0.0, 10.0], "w": [-2.0, 2.0]}
    live = DrivePreprocessor.from_settings({**PreprocessConfig(crop_top=0.4).as_dict(), "frames": 2}, ranges)
    assert live.frames == 2 and live.config.crop_top == 0.4 and live(images(1, 480, 640)[0]).shape == (1, 6, 66, 200)
    with pytest.raises(PilotlabError, match="preprocess settings: unknown param 'size'"):
        DrivePreprocessor.from_settings({"crop_top": 0.5, "size": [200, 66]}, ranges)
