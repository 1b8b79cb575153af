"""DrivingEnv: the car on a circuit as a Gymnasium environment (`gymnasium.Env`).

    env = DrivingEnv("simple_circuit", camera=CameraSpec(), renderer="pybullet")
    obs, info = env.reset(seed=0, options={"direction": "ccw"})
    obs, reward, terminated, truncated, info = env.step((v, w))           # control_period later
    obs, reward, terminated, truncated, info = env.step((v, w), duration=0.12)  # 0.12 s later

Registered as `pilotlab/FollowLine-v0` (see `pilotlab.sim.follow_line` and docs/simulator-python.md):
`gymnasium.make("pilotlab/FollowLine-v0", circuit="montreal", camera=(320, 240))` after
`import pilotlab.sim`.

Spaces (`pilotlab.sim.observation`): the observation is the camera image (uint8 RGB, H×W×3), or with
`observation="state"` the ground truth (`STATE_KEYS`), or `"image+state"` both in a Dict; without a
camera it is the state. The action is (v, w) in m/s and rad/s within the car's limits
(`actions="normalized"`: the same range mapped onto [-1, 1]²).

With `view` (a `pilotlab.data.preprocess.PreprocessConfig`), the image is not the camera's but what
that preprocessing makes of it, rendered directly (pilotlab.sim.view: the network's input at a
fraction of the cost); `info["view"]` is then that config, so a brain knows what it was given, and
`camera_image()` still renders the camera's full image (videos, stills).

`step` keeps Gymnasium's signature (`step(action)`) and adds two keyword arguments: `duration`, the
simulated seconds this command stays in force (default: `env.control_period`, 0.05 s = 20 Hz;
pilotlab's "replay" and "measured" timing modes pass max(control period, inference time) here, so a
slow brain reacts late), and `render=False` to skip the camera (obs is then None: for callers that only advance
time). Time advances in physics steps (1/120 s): a duration is rounded to the nearest step, at least
one; `info["sim_time"]` is exact. `timing="latency"` does the same inside `step` for agents that
call plain `step(action)`: the wall-clock time since the last observation was returned (or
`fixed_inference_ms`), plus `extra_latency_ms`, passes with the previous command in force before the
new one applies, and the step lasts max(control period, that time). The default, `"lockstep"`, is the
world waiting for the agent: every step lasts one control period.

In one of BehaviorMetrics' own worlds (`world="simple_circuit_white_line"`, `assets=` the folder of BM's
worlds or $PILOTLAB_BM_ASSETS; pilotlab.worlds, docs/worlds.md): the circuit is the world's (BM's
perfect-lap centreline), the car is BM's F1 size (pilotlab.sim.car.BM_F1, unless `car` says otherwise), the
camera is BM's F1 camera at the given size, the world's walls are solid
(hitting one ends the episode: "hit_wall"), and renderer "ground" draws the world fast, "pybullet"
with TinyRenderer from its meshes.

reset options (all optional): `circuit` (name or CSV path; changing it rebuilds the world),
`direction` ("cw" | "ccw"), `start` (metres along the driving direction from the start line, or
"random": uniform over the lap from the seed), `lateral` (metres left of the red line), `heading`
(radians relative to the line), `speed` (initial forward speed, m/s), `laps`, `timeout_s`,
`control_period`. The same seed and options give the same run.

Episodes end (terminated) when the laps are completed, when the car's centre leaves the road (unless
`stop_off_road=False`: then `info["off_road"]` just flags it), or when it is trapped (less than 1 m of
progress in `trapped_s` seconds, or tipped over); they are truncated at the timeout (BehaviorMetrics'
per-circuit timeout × laps, at least one lap's). The reward is the progress along the red line during
the step, in metres (negative when driving backwards). `info` holds everything BehaviorMetrics'
metrics need; see `INFO_KEYS`. A reset with no options returns to the constructor's circuit,
direction, start, laps and timeout.

`render()`: in render mode "rgb_array", the circuit from above with the path driven since the reset,
the car, and the camera view inset (`pilotlab.sim.topdown`); without a render mode, the camera image.
"""
from __future__ import annotations

import math
import numbers
import time
from typing import Any

import gymnasium
import numpy as np

from pilotlab.circuits.circuit import Circuit, wrap_angle
from pilotlab.circuits.load import get_circuit
from pilotlab.circuits.circuit import check_direction
from pilotlab.errors import PilotlabError
from pilotlab.sim.bullet import p
from pilotlab.sim.camera import CameraSpec, camera_pose
from pilotlab.sim.car import BM_F1, Car, CarSpec
from pilotlab.sim.observation import ActionSpace, check_observation, observation_space, state_vector
from pilotlab.sim.render import GroundRenderer, PybulletRenderer, check_renderer
from pilotlab.sim.world import PHYSICS_HZ, World
from pilotlab.specs.base import CONTROL_HZ, LATENCY_LIMIT_MS

TIMINGS = ("lockstep", "latency")
RESET_OPTIONS = ("circuit", "direction", "start", "lateral", "heading", "speed", "laps", "timeout_s",
                 "control_period")
INFO_KEYS = {
    "sim_time": "simulated seconds since reset",
    "dt": "simulated seconds this step lasted",
    "step": "number of steps since reset",
    "pose": "(x, y, yaw) of the car's centre, metres and radians",
    "position": "(x, y, z) of the car's centre (z at axle height)",
    "orientation": "quaternion (x, y, z, w) of the chassis",
    "speed": "forward speed, m/s",
    "yaw_rate": "rad/s, + turning left",
    "command": "(v, w) applied during this step",
    "s": "arc length of the nearest red-line point, metres in [0, circuit_length)",
    "progress": "metres driven along the red line since the start (signed, all laps)",
    "laps_completed": "whole laps completed",
    "lap_times": "sim_time at which each lap was completed",
    "lateral_offset": "signed distance from the red line, metres, + left of the driving direction",
    "distance_to_line": "|lateral_offset|",
    "heading_error": "car yaw minus red-line heading, radians in [-pi, pi)",
    "off_road": "the car's centre is off the road (|lateral_offset| > road_width / 2)",
    "termination": "None, or why the episode ended: lap_completed | off_road | hit_wall | trapped | timeout",
    "circuit": "circuit name", "direction": "cw | ccw", "circuit_length": "metres",
    "road_width": "metres",
    "view": "the PreprocessConfig the image was rendered for (None: the camera image itself)",
}


_ABOVE_ZERO, _ANY = ("laps", "timeout_s", "control_period"), ("start", "lateral", "heading", "speed")


def check_episode(settings: dict[str, Any]) -> dict[str, Any]:
    """An episode's numbers, as the command line checks them: laps, timeout and control period finite and
    above 0, start ("random" aside), lateral offset, heading and speed finite (laps=0 ended the episode at
    once as a completed lap, laps=inf never ended, start=nan raised numpy's ValueError)."""
    for name, value in settings.items():
        if name not in _ABOVE_ZERO + _ANY or value is None or (name == "start" and value == "random"):
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            other = " (or 'random')" if name == "start" else ""
            raise PilotlabError(f"{name} must be a finite number{other}, got {value!r}")
        if name in _ABOVE_ZERO and value <= 0:
            raise PilotlabError(f"{name} must be above 0, got {value!r}")
    return settings


def describe_end(termination: str | None, laps: float) -> str:
    """How a drive ended, in words for a person ("lap_completed" after 0.1 lap reads wrong)."""
    if termination == "lap_completed":
        if laps < 1:
            return f"drove the {laps:g} lap asked for"
        return f"{laps:g} lap{'' if laps == 1 else 's'} completed"
    words = {"off_road": "left the road", "hit_wall": "hit a wall", "trapped": "trapped: no progress",
             "timeout": "timed out"}
    return words.get(termination or "", "stopped")


class DrivingEnv(gymnasium.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, circuit: str | Circuit | None = None, *, direction: str = "cw",
                 camera: CameraSpec | None = CameraSpec(), renderer: str = "pybullet",
                 control_period: float = 1.0 / CONTROL_HZ, physics_hz: float = PHYSICS_HZ, walls: bool = False,
                 car: CarSpec = CarSpec(), laps: float = 1, timeout_s: float | None = None,
                 stop_off_road: bool = True, trapped_s: float = 10.0, start: float | str = 0.0,
                 observation: str | None = None, actions: str = "physical", render_mode: str | None = None,
                 timing: str = "lockstep", extra_latency_ms: float = 0.0, fixed_inference_ms: float | None = None,
                 view=None, world: str | None = None, assets=None):
        self.bm = None if world is None else _load_bm_world(world, assets, circuit)
        if self.bm is not None:
            circuit, camera = self.bm.meta["circuit"], _bm_camera(self.bm, camera)
            walls = False   # the world's own walls stand there (solid)
            car = BM_F1 if car == CarSpec() else car   # BM's small F1 unless another car is asked for
        self.camera, self.renderer_name = camera, check_renderer(renderer, walls)
        self.view = view if camera is not None else None
        self.physics_hz, self.walls, self.car_spec = physics_hz, walls, car
        self.stop_off_road, self.trapped_s = stop_off_road, trapped_s
        self._defaults = check_episode({"circuit": circuit, "direction": check_direction(direction), "laps": laps,
                                        "timeout_s": timeout_s, "control_period": control_period, "start": start})
        self.control_period = control_period
        self.observation = check_observation(observation or ("image" if camera else "state"), camera)
        self.observation_space = observation_space(self.observation, camera if self.view is None else
                                                   CameraSpec(width=self.view.width, height=self.view.height))
        self.actions = ActionSpace(car, actions)
        self.action_space = self.actions.space
        self.render_mode = _check_render_mode(render_mode)
        self.metadata = {**self.metadata, "render_fps": 1.0 / control_period}
        self.timing, self.extra_latency_s = _check_timing(timing, extra_latency_ms, fixed_inference_ms)
        self.fixed_inference_s = None if fixed_inference_ms is None else fixed_inference_ms / 1000
        self.world: World | None = None
        self.car: Car | None = None
        self._renderer = self._view = None
        self._camera_renderer = None   # with a `view`: the camera's full image (camera_image)
        self._wall_bodies: list[int] = []   # a BM world's solid walls (pybullet bodies)
        self.circuit = self._load_circuit(circuit or "simple_circuit", direction)

    # -- Gymnasium API ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)  # as Gymnasium: a later reset without a seed goes on with the same generator
        options = dict(options or {})
        unknown = set(options) - set(RESET_OPTIONS)
        if unknown:
            raise PilotlabError(f"unknown reset option(s) {sorted(unknown)}; see DrivingEnv's docstring")
        check_episode(options)
        settings = {**self._defaults, **{k: v for k, v in options.items() if k in self._defaults}}
        self.circuit = self._load_circuit(settings["circuit"], settings["direction"])
        self.control_period = float(settings["control_period"])
        self.laps = float(settings["laps"])
        self.timeout_s = settings["timeout_s"] or self.circuit.timeout_s * max(self.laps, 1.0)
        self._build_world()
        self._place_car({**options, "start": settings["start"]})
        info = self._info()
        return self._observe(True, info), info

    def step(self, action, duration: float | None = None, render: bool = True):
        if self.car is None:
            raise PilotlabError("call reset() before step()")
        command = self.actions.command(action)
        before = self._progress
        segments = self._schedule(command, duration)
        for segment_command, steps in segments:
            self.car.apply(*segment_command, speed=self._state[2])  # read after the last physics step
            self._advance(steps)
        self._steps += 1
        self._last_dt = sum(steps for _, steps in segments) / self.physics_hz
        self._termination_reason = termination = self._termination()
        truncated = termination == "timeout"
        terminated = termination is not None and not truncated
        info, self._image = self._info(), None
        return self._observe(render, info), self._progress - before, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """Render mode "rgb_array": the top-down view with the camera view inset; no render mode: the
        camera image now (None without a camera)."""
        if self.render_mode == "rgb_array":
            return self._top_down()
        return self._camera_image()

    def close(self) -> None:
        if self.world is not None:
            self.world.close()
            self.world, self.car = None, None

    def __enter__(self) -> DrivingEnv:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def sim_time(self) -> float:
        return self._physics_steps / self.physics_hz

    # -- internals ----------------------------------------------------------------------------
    def _load_circuit(self, circuit: str | Circuit, direction: str) -> Circuit:
        if self.bm is not None:
            if circuit != self.bm.meta["circuit"]:
                raise PilotlabError(f"world {self.bm.name} has its own circuit ({self.bm.meta['circuit']}); "
                                    f"a reset cannot change it to {circuit!r}")
            return self.bm.circuit(direction)
        if isinstance(circuit, Circuit):
            return circuit.directed(direction)
        return get_circuit(circuit, direction)

    def _build_world(self) -> None:
        canonical = self.circuit.directed("cw")
        if self.world is None or self.world.circuit is not canonical:
            self.close()
            meshes = self.camera is not None and self.renderer_name == "pybullet"
            self.world = World(canonical, walls=self.walls, physics_hz=self.physics_hz,
                               road_meshes=meshes and self.bm is None)
            if self.bm is not None:
                from pilotlab.worlds.bullet import add_collisions, add_visuals
                self._wall_bodies = add_collisions(self.world.client, self.bm)
                if meshes:
                    add_visuals(self.world.client, self.bm)
            self._renderer, self._camera_renderer = self._make_renderer(canonical, self.view), None
        elif self.car is not None:
            self.world.remove(self.car.body)  # a fresh car: nothing of the last episode carries over
        self.car = None

    def _make_renderer(self, canonical: Circuit, view):
        if self.camera is None:
            return None
        if self.bm is not None:
            from pilotlab.sim.view import bm_renderer
            return bm_renderer(self.bm, self.renderer_name, self.world.client, self.camera, view)
        if view is not None:  # imported here: the views need preprocessing (and torch)
            from pilotlab.sim.view import GroundView, PreprocessedView
            if self.renderer_name == "ground":
                return GroundView(canonical, self.camera, view)
            return PreprocessedView(PybulletRenderer(self.world.client, self.camera), view)
        if self.renderer_name == "pybullet":
            return PybulletRenderer(self.world.client, self.camera)
        return GroundRenderer(canonical, self.camera)

    def _place_car(self, options: dict[str, Any]) -> None:
        start = options["start"]
        if start == "random":
            start = float(self.np_random.uniform(0.0, self.circuit.length))
        elif isinstance(start, bool) or not isinstance(start, (int, float)):
            raise PilotlabError(f"reset option start must be metres along the lap or 'random', got {start!r}")
        x, y, yaw = self.circuit.start_pose(float(start), float(options.get("lateral", 0.0)))
        yaw += float(options.get("heading", 0.0))
        self.car = Car(self.world.client, self.car_spec, (x, y, yaw), speed=float(options.get("speed", 0.0)))
        if self.bm is not None:  # BM's camera sits inside the car's body, which its images never show
            self.car.hide()
        self._physics_steps, self._steps, self._last_dt = 0, 0, 0.0
        self._start_s = float(start) % self.circuit.length
        self._s, self._progress, self._lap_times = self._start_s, 0.0, []
        self._progress_marks: list[tuple[float, float]] = [(0.0, 0.0)]
        self._termination_reason, self._path, self._image = None, [], None
        self._track()

    def _schedule(self, command: tuple[float, float], duration: float | None) -> list[tuple[tuple, int]]:
        """(command, physics steps) to apply in turn during this step (see the module docstring)."""
        if duration is not None or self.timing == "lockstep":
            seconds = self.control_period if duration is None else float(duration)
            if not seconds > 0:
                raise PilotlabError(f"a step must last a positive time, got duration={seconds}")
            return [(command, max(1, round(seconds * self.physics_hz)))]
        thought = time.perf_counter() - self._observed_at if self.fixed_inference_s is None else self.fixed_inference_s
        return latency_segments(self.car.command, command, thought + self.extra_latency_s,
                                max(1, round(self.control_period * self.physics_hz)), self.physics_hz)

    def _advance(self, steps: int) -> None:
        if steps > 0:
            self.world.step(steps)
            self._physics_steps += steps
            self._last_dt = steps / self.physics_hz
            self._track()

    def _track(self) -> None:
        """Read the car's state and advance progress along the red line."""
        position, orientation, speed, yaw_rate = self.car.state()
        self._state = (position, orientation, speed, yaw_rate)
        reach = 25.0 + abs(speed) * self._last_dt * 2
        projection = self.circuit.project(position[0], position[1], near_s=self._s, window=reach)
        length = self.circuit.length
        self._progress += (projection.s - self._s + length / 2) % length - length / 2
        self._s, self._projection = projection.s, projection
        self._path.append((position[0], position[1]))
        while self._progress >= (len(self._lap_times) + 1) * length:
            self._lap_times.append(self.sim_time)
        if self._progress > self._progress_marks[-1][1] + 1.0:
            self._progress_marks.append((self.sim_time, self._progress))

    def _termination(self) -> str | None:
        if self._progress >= self.laps * self.circuit.length:
            return "lap_completed"
        if self.stop_off_road and self._off_road():
            return "off_road"
        if self._wall_bodies and self._hit_wall():
            return "hit_wall"
        if self._trapped():
            return "trapped"
        if self.sim_time >= self.timeout_s - 1e-9:
            return "timeout"
        return None

    def _hit_wall(self) -> bool:
        return any(p.getContactPoints(bodyA=self.car.body, bodyB=wall, physicsClientId=self.world.client)
                   for wall in self._wall_bodies)

    def _off_road(self) -> bool:
        return self._projection.distance > self.circuit.road_width / 2

    def _trapped(self) -> bool:
        position, orientation = self._state[:2]
        up_z = 1 - 2 * (orientation[0] ** 2 + orientation[1] ** 2)  # z of the chassis' up axis
        if up_z < 0.5:
            return True  # tipped over
        last_mark_time = self._progress_marks[-1][0]
        return self.sim_time - last_mark_time > self.trapped_s

    def _observe(self, render: bool, info: dict[str, Any]):
        """The observation (None when the caller skipped rendering)."""
        self._observed_at = time.perf_counter()
        if not render:
            return None
        if self.observation == "state":
            return state_vector(info, self.circuit)
        image = self._camera_image()
        if self.observation == "image":
            return image
        return {"image": image, "state": state_vector(info, self.circuit)}

    def _camera_image(self) -> np.ndarray | None:
        """The image the observation holds: the camera's, or with a `view` its preprocessed frame."""
        self._image = self._render_with(self._renderer)
        return self._image

    def camera_image(self) -> np.ndarray | None:
        """The camera's full image now, even with a `view` (videos and stills of a run; None without a
        camera)."""
        if self.view is None:
            return self._camera_image()
        if self._camera_renderer is None and self.world is not None:
            self._camera_renderer = self._make_renderer(self.circuit.directed("cw"), None)
        return self._render_with(self._camera_renderer)

    def _render_with(self, renderer) -> np.ndarray | None:
        if renderer is None or self.car is None:
            return None
        position, orientation = self._state[:2]
        eye, rotation = camera_pose(self.camera, position, orientation, self.car_spec.wheel_radius)
        return renderer.render(eye, rotation)

    def _top_down(self) -> np.ndarray:
        if self.car is None:
            raise PilotlabError("call reset() before render()")
        canonical = self.circuit.directed("cw")
        if self._view is None or self._view[0] is not canonical:
            from pilotlab.sim.topdown import TopDownView
            self._view = (canonical, TopDownView(canonical))
        camera = self._image if self._image is not None else self._camera_image()
        x, y, yaw = self._info()["pose"]
        return self._view[1].draw(np.array(self._path), (x, y, yaw), self.car_spec.body_length, camera)

    def _info(self) -> dict[str, Any]:
        position, orientation, speed, yaw_rate = self._state
        yaw = math.atan2(2 * (orientation[3] * orientation[2] + orientation[0] * orientation[1]),
                         1 - 2 * (orientation[1] ** 2 + orientation[2] ** 2))
        projection, circuit = self._projection, self.circuit
        return {
            "sim_time": self.sim_time, "dt": self._last_dt, "step": self._steps,
            "pose": (position[0], position[1], yaw), "position": tuple(position), "orientation": tuple(orientation),
            "speed": speed, "yaw_rate": yaw_rate, "command": self.car.command,
            "s": projection.s, "progress": self._progress, "laps_completed": len(self._lap_times),
            "lap_times": list(self._lap_times), "lateral_offset": projection.lateral,
            "distance_to_line": projection.distance,
            "heading_error": float(wrap_angle(yaw - projection.heading)), "off_road": self._off_road(),
            "termination": self._termination_reason, "circuit": circuit.name, "direction": circuit.direction,
            "circuit_length": circuit.length, "road_width": circuit.road_width, "view": self.view,
        }


def latency_segments(previous: tuple[float, float], command: tuple[float, float], brain_s: float,
                     period_steps: int, physics_hz: float) -> list[tuple[tuple[float, float], int]]:
    """The latency timing mode: `previous` stays in force while the brain thinks (`brain_s`, rounded
    up to whole physics steps: a command ready mid-step applies from the next one), then `command`,
    for max(control period, thinking time) in all (as `pilotlab.online.drive.LatencyClock`)."""
    late = math.ceil(brain_s * physics_hz - 1e-6)
    total = max(period_steps, late)
    return [(previous, late), (command, total - late)]


def _load_bm_world(world: str, assets, circuit):
    from pilotlab.worlds import load_world   # imported here: only BM worlds need trimesh
    if circuit is not None:
        raise PilotlabError(f"give a circuit or a world, not both: world {world!r} has its own circuit")
    return load_world(world, assets)


def _bm_camera(bm, camera: CameraSpec | None) -> CameraSpec | None:
    """In a BM world the car's camera is the world's own (BM's F1 camera: its optics and mount); the
    given camera chooses only the image size and window."""
    if camera is None:
        return None
    return bm.camera(width=camera.width, height=camera.height, window=camera.window)


def _check_render_mode(render_mode: str | None) -> str | None:
    if render_mode not in (None, *DrivingEnv.metadata["render_modes"]):
        raise PilotlabError(f"unknown render_mode {render_mode!r}; use one of: "
                            f"{', '.join(DrivingEnv.metadata['render_modes'])} (or None)")
    return render_mode


def _check_timing(timing: str, extra_latency_ms: float, fixed_inference_ms: float | None) -> tuple[str, float]:
    if timing not in TIMINGS:
        raise PilotlabError(f"unknown timing {timing!r}; use one of: {', '.join(TIMINGS)}")
    given = [extra_latency_ms] + ([] if fixed_inference_ms is None else [fixed_inference_ms])
    # outside test: NaN failed in the first step with numpy's words; 1e7 ms simulated for minutes in one step
    if not all(isinstance(ms, numbers.Real) and 0 <= ms <= LATENCY_LIMIT_MS for ms in given):
        raise PilotlabError(f"extra_latency_ms and fixed_inference_ms must be numbers of milliseconds from 0 to "
                            f"{LATENCY_LIMIT_MS:,.0f}; got {', '.join(repr(ms) for ms in given)}")
    if timing == "lockstep" and (extra_latency_ms or fixed_inference_ms is not None):
        raise PilotlabError("extra_latency_ms and fixed_inference_ms only mean something with timing='latency'")
    return timing, extra_latency_ms / 1000
