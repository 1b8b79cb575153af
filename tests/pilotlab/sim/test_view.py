"""The network's view rendered in the loop against the recorded frame read and preprocessed."""
import numpy as np
import pytest

from pilotlab.data.bags import read_bag
from pilotlab.data.preprocess import PreprocessConfig
from pilotlab.sim.camera import GROUND, LINE, ROAD, SKY, CameraSpec, PixelGrid
from pilotlab.sim.env import DrivingEnv
from pilotlab.sim.expert import Expert
from pilotlab.sim.record import RecordSpec, record
from pilotlab.sim.view import network_grid

SECONDS = 8.0   # of simple_circuit from the start line: a straight and the first bend


def replay_with_view(config: PreprocessConfig, frames: int, every: int):
    """Drive as the record job does (the expert, no noise) with the env rendering `config`'s view:
    the same poses as the recording (pybullet is deterministic); (view frames, commands at them)."""
    with DrivingEnv("simple_circuit", camera=CameraSpec(), renderer="ground", view=config) as env:
        obs, info = env.reset(seed=0, options={"start": 0.0})
        assert info["view"] == config
        expert, views, commands = Expert(env.circuit), [], []
        for step in range(frames * every):
            command = expert.act(info)
            if step % every == 0:
                views.append(obs if obs is not None else env.render())
                commands.append(command)
            obs, _, _, _, info = env.step(command, render=False)
    return np.stack(views), np.array(commands, np.float32)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A raw rgb8 640×480 recording (the record job's defaults) of the first seconds of simple_circuit."""
    return record(RecordSpec(circuit="simple_circuit", max_seconds=SECONDS), tmp_path_factory.mktemp("rec") / "lap")


def compare(recording, config: PreprocessConfig):
    recorded = read_bag(recording.path, config)
    views, commands = replay_with_view(config, len(recorded), every=2)   # 10 Hz frames, 20 Hz commands
    np.testing.assert_allclose(commands, recorded.labels, atol=1e-6)     # the same poses, hence decisions
    difference = np.abs(views.astype(int) - recorded.frames.astype(int))
    return difference.mean(axis=(1, 2, 3)), (difference.max(axis=3) > 10).mean(axis=(1, 2)), difference.max()


def largest_contrast() -> int:
    """The largest channel difference between two colours of the world (sky and grass: 165)."""
    colours = np.array([SKY, GROUND, ROAD, LINE])
    return int(np.abs(colours[:, None] - colours[None]).max())


def test_the_view_is_the_recorded_frame_preprocessed_within_edge_sampling(recording):
    # "fast_area" averages 2×2 blocks of the 640×240 crop; the view samples each block once at its
    # centre. Away from edges the two are equal; where an edge (line, road, horizon) crosses a block the
    # view has one side's colour instead of the mix, so a single pixel may differ by up to the largest
    # contrast of the world's colours while few pixels differ at all. Measured here: frame means
    # 0.3-0.7 grey levels, at most ~3 % of pixels more than 10 levels apart, about what moving the
    # camera by one full-frame pixel (0.1°) changes. The bounds leave room for other stretches of road;
    # a wrong crop or swapped channels gives frame means above 10 and ~40 % of pixels.
    means, far, worst = compare(recording, PreprocessConfig())
    print(f"\nview vs recorded, fast_area: mean {means.mean():.2f} (worst frame {means.max():.2f}), "
          f"pixels > 10 apart {100 * far.mean():.2f} % (worst {100 * far.max():.2f} %), max {worst}")
    assert means.mean() < 0.5 and means.max() < 1.0
    assert far.max() < 0.05
    assert worst <= largest_contrast()


def test_with_area_interpolation_the_view_renders_the_crop_at_full_resolution(recording):
    # The same samples as the recorded frame's rows: only floating-point rounding in the warp's
    # coordinates can flip a pixel on an edge (measured: means < 0.1, < 0.1 % of pixels).
    means, far, _ = compare(recording, PreprocessConfig(interpolation="area"))
    assert means.max() < 0.3
    assert far.max() < 0.005


def test_the_grid_samples_each_averaged_block_at_its_centre():
    camera = CameraSpec()
    assert network_grid(camera, PreprocessConfig()) == PixelGrid(320, 120, 2.0, 0.5, 240.5)
    assert network_grid(camera, PreprocessConfig(width=100, height=40)) == PixelGrid(160, 60, 4.0, 1.5, 241.5)
    assert network_grid(camera, PreprocessConfig(interpolation="area")) == PixelGrid(640, 240, 1.0, 0.0, 240.0)
    assert network_grid(camera, PreprocessConfig(crop_top=0.4, crop_bottom=0.9)) == PixelGrid(320, 120, 2.0, 0.5,
                                                                                                  192.5)
