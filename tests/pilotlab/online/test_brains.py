"""Brains: the network brain feeds the network what training fed it and de-normalises its output;
temporal models get frames spaced as in training; the reference brains are a registry."""
import numpy as np
import pytest

from matrix.errors import UnknownNameError
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.data.preprocess import PreprocessConfig, preprocess
from pilotlab.errors import PilotlabError
from pilotlab.online.brains import (REFERENCE_BRAINS, ExplicitReference, FrameStack, NetworkBrain,
                                    make_reference_brain)
from pilotlab.predictor import load_predictor
from pilotlab.strategies.artifact import read_meta, write_meta


def camera_images(count: int, seed: int = 0) -> np.ndarray:
    """640x480 RGB images with a red stripe somewhere in the lower half."""
    rng = np.random.default_rng(seed)
    images = rng.integers(60, 140, (count, 480, 640, 3), dtype=np.uint8)
    for image, column in zip(images, rng.integers(100, 540, count)):
        image[240:, column - 8:column + 8] = (205, 30, 30)
    return images


def test_the_network_sees_exactly_the_training_input(pilotnet_artifact):
    predictor = load_predictor(pilotnet_artifact, "cpu1")
    brain = NetworkBrain(predictor)
    images = camera_images(3)
    # Training's input: preprocessed frames in a FrameSet, turned into tensors by FrameSet.inputs.
    config = PreprocessConfig()
    saved = FrameSet(np.stack([preprocess(image, config) for image in images]), np.zeros((3, 2), np.float32),
                     np.zeros(3, np.int32))
    for i, image in enumerate(images):
        brain.reset(None)
        np.testing.assert_array_equal(brain.inputs(image, 0.0), saved.inputs(np.array([i])).numpy())


def test_the_command_is_the_de_normalised_output(pilotnet_artifact):
    predictor = load_predictor(pilotnet_artifact, "cpu1")
    brain, image = NetworkBrain(predictor), camera_images(1)[0]
    ranges = LabelRanges.from_dict(predictor.meta.labels)
    expected = ranges.denormalise(predictor.predict(brain.inputs(image, 0.0)))[0]
    brain.reset(None)
    v, w = brain.act(image, {"sim_time": 0.0})
    assert (v, w) == pytest.approx(tuple(expected), rel=1e-5)
    assert brain.last_inference_s > 0 and brain.name == "baseline"


def test_a_temporal_model_gets_frames_spaced_as_in_training(stacked_artifact):
    brain = NetworkBrain(load_predictor(stacked_artifact, "cpu1"), frame_interval_s=0.1)
    assert brain.frames == 2
    images = camera_images(4, seed=3)
    frames = [preprocess(image, brain.config) for image in images]
    # Images every 0.05 s: the stack pairs each one with the one 0.1 s earlier (two iterations back).
    stacks = [brain.inputs(image, 0.05 * i) for i, image in enumerate(images)]
    as_input = lambda frame: np.transpose(frame, (2, 0, 1)).astype(np.float32) / 255
    np.testing.assert_allclose(stacks[0][0, :3], as_input(frames[0]))     # no history: the first repeated
    np.testing.assert_allclose(stacks[0][0, 3:], as_input(frames[0]))
    np.testing.assert_allclose(stacks[3][0, :3], as_input(frames[1]))
    np.testing.assert_allclose(stacks[3][0, 3:], as_input(frames[3]))
    v, w = brain.act(images[0], {"sim_time": 0.2})
    assert np.isfinite([v, w]).all()


def test_frame_stack_picks_the_nearest_frames_in_time():
    stack = FrameStack(3, 0.1)
    picked = [stack.push(np.full((1, 1, 3), i, np.uint8), t)[:, 0, 0, 0].tolist()
              for i, t in enumerate([0.0, 0.04, 0.1, 0.15, 0.21])]
    assert picked[0] == [0, 0, 0] and picked[2] == [0, 0, 2]
    assert picked[4] == [0, 2, 4]     # targets 0.01, 0.11, 0.21: nearest 0.0, 0.1, 0.21
    # A slow brain leaves gaps: targets 0.3, 0.4, 0.5 get the nearest frames there are, 0.21, 0.5, 0.5.
    assert stack.push(np.full((1, 1, 3), 5, np.uint8), 0.5)[:, 0, 0, 0].tolist() == [4, 5, 5]
    assert stack.times == [0.15, 0.21, 0.5]  # older frames than the stack can reach are dropped


def test_the_baseline_strategy_keeps_a_stacked_models_input(stacked_artifact, tmp_path):
    from pilotlab.strategies.apply import StrategySource, apply_strategy
    apply_strategy("baseline", {}, StrategySource(stacked_artifact / "model.pt", tmp_path / "out"))
    assert read_meta(tmp_path / "out").input_shape == (None, 6, 66, 200)


def test_a_checkpoint_whose_preprocessing_does_not_fit_its_network_is_refused(pilotnet_artifact, tmp_path):
    import shutil
    copy = tmp_path / "artifact"
    shutil.copytree(pilotnet_artifact, copy)
    meta = read_meta(copy)
    write_meta(copy, type(meta)(**{**meta.__dict__, "preprocess": {**meta.preprocess, "height": 100}}))
    with pytest.raises(PilotlabError, match="takes \\[N, 3, 66, 200\\] but its preprocessing makes 1 frame"):
        NetworkBrain(load_predictor(copy, "cpu1"))


def test_reference_brains_are_a_registry_with_checked_options():
    assert REFERENCE_BRAINS.names() == ["explicit", "expert"]
    brain = make_reference_brain("explicit", {"max_speed": 9.0, "near_rows": [0.7, 0.8]})
    assert isinstance(brain, ExplicitReference) and brain.brain.config.near_rows == (0.7, 0.8)
    with pytest.raises(PilotlabError, match="unknown option.s. top_sped .did you mean 'top_speed'..; known: top_speed"):
        make_reference_brain("expert", {"top_sped": 3})
    with pytest.raises(PilotlabError, match="max_speed"):
        make_reference_brain("explicit", {"max_speed": "fast"})
    with pytest.raises(UnknownNameError, match="did you mean 'expert'"):
        make_reference_brain("expret")


def test_in_the_loop_the_network_is_given_its_view_and_uses_it_as_is(pilotnet_artifact, tmp_path):
    from pilotlab.online.evaluate import OnlineSpec, make_env, run_all
    brain = NetworkBrain(load_predictor(pilotnet_artifact, "cpu1"))
    spec = OnlineSpec(circuit="simple_circuit", timeout_s=0.5, timing="measured")
    with make_env(spec, camera=True, view=brain.view) as env:
        frame, info = env.reset(seed=0)
    assert frame.shape == (66, 200, 3) and info["view"] == brain.config
    np.testing.assert_array_equal(brain.inputs(frame, 0.0, info["view"])[0],
                                  np.transpose(frame, (2, 0, 1)).astype(np.float32) / 255)
    # A camera image of another size is preprocessed, not taken for the frame.
    full = camera_images(1)[0]
    brain.reset(None)
    np.testing.assert_array_equal(brain.inputs(full, 0.0, None), brain.inputs(full, 0.0, PreprocessConfig(width=8)))
    # The lap's stills are the full camera image, while the network is given its view.
    trajectories, media, _ = run_all(brain, spec, tmp_path)
    assert trajectories[0].meta["termination"] == "timeout" and media["camera_frames"]
    import cv2
    assert cv2.imread(str(tmp_path / media["camera_frames"][0])).shape == (480, 640, 3)


def test_the_explicit_brain_steers_the_same_on_its_view_as_on_the_full_frame():
    """In the loop the explicit brain is given the lower half at half resolution (its view); on the same
    frames it decides as on the full frame (to a pixel of half resolution), and in a lap it drives the same."""
    from pilotlab.online.drive import drive
    from pilotlab.online.evaluate import OnlineSpec, make_env
    from pilotlab.online.metrics import position_deviation_mae_m
    brain = ExplicitReference(REFERENCE_BRAINS.get("explicit").config_cls())
    assert (brain.view.crop_top, brain.view.width, brain.view.height) == (0.5, 320, 120)
    for column in (120, 301, 333, 500):       # a grey frame, a red stripe below the horizon
        image = np.full((480, 640, 3), 100, np.uint8)
        image[240:, column - 8:column + 8] = (205, 30, 30)
        brain.reset(None)
        full = brain.act(image, {"view": None})
        brain.reset(None)
        half = brain.act(image[240::2, ::2], {"view": brain.view})
        # a pixel at half resolution is 0.006 of the offset: kp (2) times it in w, slow_down (10) in v
        assert half[0] == pytest.approx(full[0], abs=0.1) and half[1] == pytest.approx(full[1], abs=0.02)
    spec = OnlineSpec(circuit="simple_circuit", timing="replay", brain="explicit", fixed_inference_ms=0.0)
    laps = {}
    for view in (None, brain.view):
        with make_env(spec, camera=True, view=view) as env:
            brain.reset(env.circuit)
            laps[view is None] = drive(env, brain, spec)
    assert all(lap.termination == "lap_completed" for lap in laps.values())
    assert laps[True].t[-1] == pytest.approx(laps[False].t[-1], abs=1.0)    # 59.1 and 59.0 s measured
    assert position_deviation_mae_m(laps[True]) == pytest.approx(position_deviation_mae_m(laps[False]), abs=0.01)
