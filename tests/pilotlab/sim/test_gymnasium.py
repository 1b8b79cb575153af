"""DrivingEnv in the Gymnasium ecosystem: the env checker, `gymnasium.make` and its wrappers, a vector
env, seeding, rendering, the latency timing mode; on the 110 m stadium with a tiny camera."""
import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.wrappers import RecordEpisodeStatistics, TimeLimit

import pilotlab.sim  # noqa: F401  (registers pilotlab/FollowLine-v0)
from pilotlab.errors import PilotlabError
from pilotlab.sim.camera import SKY
from pilotlab.sim.env import DrivingEnv
from pilotlab.sim.expert import Expert
from pilotlab.sim.follow_line import ENV_ID
from pilotlab.sim.observation import STATE_KEYS
from pilotlab.sim.topdown import PATH

SMALL = (48, 36)
STRAIGHT = np.array([6.0, 0.0], np.float32)


def make(stadium_csv, **options):
    """The registered env; these tests drive in m/s and rad/s unless they say `actions`."""
    options.setdefault("actions", "physical")
    return gymnasium.make(ENV_ID, circuit=stadium_csv, camera=options.pop("camera", SMALL), **options)


def checker_warnings(env) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    return [str(w.message) for w in caught]


@pytest.mark.parametrize("options", [{"observation": "image"}, {"observation": "state", "camera": None},
                                     {"observation": "image+state"}])
def test_the_env_checker_passes_without_warnings(stadium_csv, options):
    """As users make it: normalized actions are the registered default."""
    with gymnasium.make(ENV_ID, circuit=stadium_csv, camera=options.pop("camera", SMALL), **options) as env:
        assert checker_warnings(env) == []
        assert list(env.action_space.low) == [-1, -1] and list(env.action_space.high) == [1, 1]
        env.reset(seed=0)
        _, _, _, _, info = env.step(np.array([1.0, 0.0], np.float32))
        assert info["command"] == pytest.approx((25.0, 0.0), abs=1e-5)    # physical units in info: full speed


def test_with_physical_actions_the_checker_only_recommends_normalizing(stadium_csv):
    """(v, w) in m/s and rad/s; Gymnasium's checker recommends [-1, 1] for any other Box action
    range (Pendulum-v1 gets the same), which the default `actions="normalized"` gives."""
    with make(stadium_csv, actions="physical") as env:
        caught = checker_warnings(env)
        assert len(caught) == 1 and "recommend using a symmetric and normalized space" in caught[0]
        assert env.action_space.low[0] == -5.0 and env.action_space.high[0] == 25.0   # CarSpec's limits
        assert env.action_space.high[1] == pytest.approx(25.0 * np.tan(0.6) / 1.6)


def test_spaces_follow_the_options(stadium_csv):
    with make(stadium_csv, observation="image+state") as env:
        obs, _ = env.reset(seed=0)
        assert env.observation_space["image"].shape == (36, 48, 3) and obs["image"].dtype == np.uint8
        assert obs["state"].shape == (len(STATE_KEYS),) and obs in env.observation_space
    with make(stadium_csv, camera="crop") as env:
        assert env.observation_space.shape == (66, 200, 3)
    with make(stadium_csv, camera=None) as env:   # no camera: the ground truth
        obs, info = env.reset(seed=0)
        assert obs.dtype == np.float32 and obs[list(STATE_KEYS).index("speed")] == 0.0
    with pytest.raises(PilotlabError, match="needs a camera"):
        make(stadium_csv, camera=None, observation="image")
    with pytest.raises(PilotlabError, match="camera"):
        make(stadium_csv, camera="big")
    with pytest.raises(PilotlabError, match=r"camera 100000×100000 is too large: at most 4096 pixels a side"):
        make(stadium_csv, camera=(100000, 100000))


def test_normalized_actions_map_onto_the_car_limits(stadium_csv):
    with make(stadium_csv, actions="normalized") as env:
        env.reset(seed=0)
        actions = env.unwrapped.actions
        action = actions.action(6.0, -0.5)
        assert actions.command(action) == pytest.approx((6.0, -0.5), abs=1e-5)
        _, _, _, _, info = env.step(action)
        assert info["command"] == pytest.approx((6.0, -0.5), abs=1e-5)


def test_max_episode_steps_time_limit_and_episode_statistics(stadium_csv):
    env = RecordEpisodeStatistics(make(stadium_csv, max_episode_steps=8))
    _, info = env.reset(seed=0)
    rewards = []
    for _ in range(20):
        _, reward, terminated, truncated, info = env.step(STRAIGHT)
        rewards.append(reward)
        if terminated or truncated:
            break
    assert truncated and not terminated and len(rewards) == 8
    assert info["episode"]["l"] == 8 and info["episode"]["r"] == pytest.approx(sum(rewards))
    assert sum(rewards) == pytest.approx(info["progress"]) and info["progress"] > 0
    env.close()
    with TimeLimit(DrivingEnv(stadium_csv, camera=None), max_episode_steps=3) as limited:
        limited.reset(seed=0)
        assert [limited.step(STRAIGHT)[3] for _ in range(3)] == [False, False, True]


def test_the_env_s_own_timeout_truncates(stadium_csv):
    with make(stadium_csv, camera=None, timeout_s=0.5) as env:
        env.reset(seed=0)
        steps = [env.step(STRAIGHT) for _ in range(10)]
        assert [s[3] for s in steps] == [False] * 9 + [True] and steps[-1][4]["termination"] == "timeout"


def run(env, seed: int, steps: int = 15):
    obs, info = env.reset(seed=seed)
    observations, poses = [obs], [info["pose"]]
    for i in range(steps):
        obs, _, _, _, info = env.step(np.array([7.0, 0.4 * np.sin(i / 3)], np.float32))
        observations.append(obs)
        poses.append(info["pose"])
    return observations, poses


def test_seeds_reproduce_runs(stadium_csv):
    with make(stadium_csv, start="random") as first, make(stadium_csv, start="random") as second:
        frames_a, poses_a = run(first, seed=11)
        frames_b, poses_b = run(second, seed=11)
        _, poses_c = run(first, seed=12)
    assert poses_a == poses_b and all(np.array_equal(a, b) for a, b in zip(frames_a, frames_b))
    assert poses_c[0] != poses_a[0]   # another seed, another random start


def vector(stadium_csv):
    return gymnasium.vector.SyncVectorEnv([lambda: make(stadium_csv, start="random")] * 2)


def test_a_sync_vector_env_of_two(stadium_csv):
    envs = vector(stadium_csv)
    first, info = envs.reset(seed=3)
    assert first.shape == (2, 36, 48, 3) and envs.single_action_space.shape == (2,)
    assert info["s"][0] != info["s"][1]          # seeds 3 and 4: two random starts
    for _ in range(4):
        obs, rewards, terminated, truncated, info = envs.step(np.stack([STRAIGHT, STRAIGHT]))
    assert obs.shape == (2, 36, 48, 3) and rewards.shape == (2,) and np.all(rewards > 0)
    assert list(info["circuit"]) == ["stadium", "stadium"] and not terminated.any() and not truncated.any()
    envs.close()
    again = vector(stadium_csv)
    assert np.array_equal(again.reset(seed=3)[0], first)
    again.close()


def test_rgb_array_shows_the_circuit_the_path_and_the_camera(stadium_csv):
    with make(stadium_csv, render_mode="rgb_array") as env:
        env.reset(seed=0)
        first = env.render()
        for _ in range(40):
            env.step(STRAIGHT)
        frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3 and max(frame.shape) == 480
    path = np.all(frame == PATH, axis=2)
    assert path.sum() > 40 and not np.all(first == PATH, axis=2).any()   # the path appears as the car drives
    assert np.all(frame[0, :100] == 255) and np.all(frame[2:6, 2:100] == SKY)  # the camera view, framed, top left
    assert env.metadata["render_fps"] == 20


def test_latency_timing_keeps_the_previous_command_while_the_agent_thinks(stadium_csv):
    with make(stadium_csv, camera=None, timing="latency", fixed_inference_ms=120.0) as env:
        env.reset(seed=0)
        _, _, _, _, info = env.step(STRAIGHT)
        assert info["sim_time"] == pytest.approx(15 / 120)       # max(50 ms, 120 ms rounded up to physics steps)
    with make(stadium_csv, camera=None, timing="latency", extra_latency_ms=30.0) as env:
        env.reset(seed=0)
        assert env.step(STRAIGHT)[4]["sim_time"] == pytest.approx(0.05)   # 30 ms + a few: within the period
    with pytest.raises(PilotlabError, match="timing='latency'"):
        make(stadium_csv, extra_latency_ms=10.0)


def test_the_expert_drives_a_lap_of_the_registered_env(stadium_csv):
    with make(stadium_csv, camera=None) as env:
        _, info = env.reset(seed=0)
        expert = Expert(env.unwrapped.circuit)
        total, done = 0.0, False
        while not done:
            _, reward, terminated, truncated, info = env.step(expert.act(info))
            total, done = total + reward, terminated or truncated
    assert info["termination"] == "lap_completed" and total == pytest.approx(info["progress"])


def test_importing_pilotlab_sim_registers_the_env_without_importing_gymnasium():
    """Planning imports pilotlab.sim; gymnasium is imported only by whoever uses it."""
    code = ("import sys, importlib.util, pilotlab.sim; assert 'gymnasium' not in sys.modules; "
            "assert importlib.util.find_spec('gymnasium'); import gymnasium; "   # a look first, then the import
            f"assert {ENV_ID!r} in gymnasium.registry; print('ok')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == "ok", done.stderr
