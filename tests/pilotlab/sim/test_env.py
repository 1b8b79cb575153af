import numpy as np
import pytest

from pilotlab.errors import PilotlabError
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import INFO_KEYS, DrivingEnv
from pilotlab.sim.expert import Expert

SMALL = CameraSpec(width=48, height=36)


def run(env, commands, **reset):
    obs, info = env.reset(**reset)
    frames, infos = [obs], [info]
    for command in commands:
        obs, reward, terminated, truncated, info = env.step(command)
        frames.append(obs)
        infos.append(info)
        if terminated or truncated:
            break
    return frames, infos


def test_reset_and_step_follow_gymnasium(stadium_csv):
    with DrivingEnv(stadium_csv, camera=SMALL, renderer="ground") as env:
        obs, info = env.reset(seed=3)
        assert obs.shape == (36, 48, 3) and obs.dtype == np.uint8
        assert set(INFO_KEYS) <= set(info)
        assert info["sim_time"] == 0 and info["progress"] == 0 and info["distance_to_line"] < 0.01
        obs, reward, terminated, truncated, info = env.step((5.0, 0.0))
        assert obs.shape == (36, 48, 3) and not terminated and not truncated
        assert info["sim_time"] == pytest.approx(0.05) and info["dt"] == pytest.approx(0.05)
        assert info["command"] == (5.0, 0.0) and reward == pytest.approx(info["progress"]) and reward > 0
        (_, w_max) = env.car.spec.command_bounds[1]
        assert env.step((40.0, -50.0))[4]["command"] == pytest.approx((25.0, -w_max))   # clipped, w too (outside test)
        with pytest.raises(PilotlabError, match="finite"):
            env.step((float("nan"), 0.0))
        with pytest.raises(PilotlabError, match="unknown reset option"):
            env.reset(options={"strat": 3})


def test_each_step_can_last_a_chosen_simulated_time(stadium_csv):
    with DrivingEnv(stadium_csv, camera=None) as env:
        env.reset()
        _, _, _, _, info = env.step((5.0, 0.0), duration=0.125)  # a slow brain: 125 ms of inference
        assert info["dt"] == pytest.approx(0.125) and info["sim_time"] == pytest.approx(0.125)
        _, _, _, _, info = env.step((5.0, 0.0), duration=0.012)  # rounded to the 1/120 s physics step
        assert info["dt"] == pytest.approx(1 / 120)
        env.control_period = 0.1
        obs, _, _, _, info = env.step((5.0, 0.0), render=False)
        assert obs is None and info["sim_time"] == pytest.approx(0.125 + 1 / 120 + 0.1)
        env.reset(options={"control_period": 0.2})
        assert env.step((1.0, 0.0))[4]["sim_time"] == pytest.approx(0.2)


def test_the_same_seed_gives_the_same_run(stadium_csv):
    commands = [(8.0, 0.3 * np.sin(i / 5)) for i in range(40)]
    options = {"start": "random", "lateral": 0.5}
    with DrivingEnv(stadium_csv, camera=SMALL, renderer="pybullet") as first:
        frames_a, infos_a = run(first, commands, seed=7, options=options)
        frames_b, infos_b = run(first, commands, seed=7, options=options)  # same env, reset again
    with DrivingEnv(stadium_csv, camera=SMALL, renderer="pybullet") as second:
        frames_c, infos_c = run(second, commands, seed=7, options=options)
        _, infos_d = run(second, commands, seed=8, options=options)
    for other_frames, other_infos in ((frames_b, infos_b), (frames_c, infos_c)):
        assert [i["pose"] for i in infos_a] == [i["pose"] for i in other_infos]
        assert all(np.array_equal(a, b) for a, b in zip(frames_a, other_frames))
    assert infos_d[0]["s"] != infos_a[0]["s"]  # another seed, another random start


def test_leaving_the_road_terminates_the_episode(stadium_csv):
    with DrivingEnv(stadium_csv, camera=None) as env:
        _, infos = run(env, [(6.0, 0.0)] * 100, options={"heading": 0.5})
        assert infos[-1]["termination"] == "off_road" and infos[-1]["off_road"]
        assert infos[-1]["distance_to_line"] > env.circuit.road_width / 2
    with DrivingEnv(stadium_csv, camera=None, stop_off_road=False, timeout_s=6.0) as env:
        _, infos = run(env, [(6.0, 0.0)] * 200, options={"heading": 0.5})
        assert infos[-1]["termination"] == "timeout" and any(i["off_road"] for i in infos)


def test_timeout_truncates_and_standing_still_traps(stadium_csv):
    with DrivingEnv(stadium_csv, camera=None, timeout_s=1.0) as env:
        _, infos = run(env, [(5.0, 0.0)] * 100)
        assert infos[-1]["termination"] == "timeout" and infos[-1]["sim_time"] == pytest.approx(1.0)
    with DrivingEnv(stadium_csv, camera=None, trapped_s=2.0) as env:
        obs, info = env.reset()
        for _ in range(100):
            _, _, terminated, truncated, info = env.step((0.0, 0.0))
            if terminated:
                break
        assert terminated and not truncated and info["termination"] == "trapped"
        assert info["sim_time"] == pytest.approx(2.05, abs=0.06)


def test_laps_are_counted_in_both_directions(stadium_csv):
    for direction in ("cw", "ccw"):
        with DrivingEnv(stadium_csv, camera=None, direction=direction, laps=2) as env:
            obs, info = env.reset(options={"start": 20.0})
            expert = Expert(env.circuit)
            rewards = []
            while True:
                _, reward, terminated, truncated, info = env.step(expert.act(info), render=False)
                rewards.append(reward)
                if terminated or truncated:
                    break
            assert info["termination"] == "lap_completed" and info["laps_completed"] == 2
            assert len(info["lap_times"]) == 2 and 0 < info["lap_times"][0] < info["lap_times"][1]
            assert sum(rewards) == pytest.approx(info["progress"]) and info["progress"] >= 2 * env.circuit.length
            assert info["direction"] == direction


def test_reset_can_change_circuit_and_direction(stadium_csv):
    with DrivingEnv(stadium_csv, camera=SMALL, renderer="pybullet") as env:
        _, info = env.reset(options={"circuit": "simple_circuit", "direction": "ccw", "start": 100.0})
        assert info["circuit"] == "simple_circuit" and info["direction"] == "ccw"
        assert info["s"] == pytest.approx(100.0, abs=0.05)
        assert env.timeout_s == pytest.approx(82.5)
        world = env.world
        env.reset(options={"circuit": "simple_circuit", "direction": "cw"})
        assert env.world is world  # the same road: the world is kept, only the car is new
        _, info = env.reset()
        assert info["circuit"] == "stadium"


@pytest.mark.parametrize("settings, message", [
    ({"laps": 0}, "laps must be above 0"), ({"laps": -1}, "laps must be above 0"),
    ({"laps": float("inf")}, "laps must be a finite number"), ({"start": float("nan")}, "start must be a finite number"),
    ({"timeout_s": 0}, "timeout_s must be above 0"), ({"start": "middle"}, "(or 'random')"),
])
def test_episode_settings_the_command_line_refuses_are_refused_here_too(stadium_csv, settings, message):
    """Outside test: laps=0 ended the first step as a completed lap, laps=inf never ended, start=nan
    raised numpy's ValueError; as constructor arguments and as reset options."""
    with pytest.raises(PilotlabError, match=message.replace("(", r"\(").replace(")", r"\)")):
        DrivingEnv(stadium_csv, camera=None, observation="state", **settings)
    with DrivingEnv(stadium_csv, camera=None, observation="state") as env:
        with pytest.raises(PilotlabError, match=message.replace("(", r"\(").replace(")", r"\)")):
            env.reset(options=settings)


@pytest.mark.parametrize("options", [{"fixed_inference_ms": float("nan")}, {"fixed_inference_ms": 1e7},
                                     {"extra_latency_ms": -1.0}, {"extra_latency_ms": float("inf")}])
def test_latencies_that_are_no_number_of_milliseconds_are_refused_when_made(stadium_csv, options):
    """Outside test: NaN failed at the first step in numpy's words; 1e7 ms simulated for minutes in one step."""
    with pytest.raises(PilotlabError, match="must be numbers of milliseconds from 0 to 60,000"):
        DrivingEnv(stadium_csv, camera=None, timing="latency", **options)


def test_an_env_dropped_without_close_lets_its_physics_client_go(stadium_csv):
    """Outside test: 40 envs dropped without close() kept 41 pybullet clients (and 300 MB) alive."""
    import gc
    env = DrivingEnv(stadium_csv, camera=None)
    env.reset(seed=0)
    client = env.world.client
    del env
    gc.collect()
    from pilotlab.sim.bullet import p
    assert not p.isConnected(physicsClientId=client)
