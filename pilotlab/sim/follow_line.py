"""`pilotlab/FollowLine-v0`: DrivingEnv registered with Gymnasium, its options as `make` keywords.

    import gymnasium, pilotlab.sim
    env = gymnasium.make("pilotlab/FollowLine-v0", circuit="simple_circuit", direction="ccw",
                         camera=(320, 240), control_hz=20, max_episode_steps=2000)

Keywords (all optional): `circuit` (a name, `pilotlab circuit list`, or a CSV path), `direction`
("cw" | "ccw"), `camera` ((width, height), a dict of `CameraSpec` fields, a `CameraSpec`, "crop" for
the network's 200×66 input rendered directly, or None for no camera), `renderer` ("ground", the fast
one, or "pybullet"), `observation` ("image" | "state" | "image+state"), `actions` ("normalized",
the default here: [-1, 1]² mapped onto the car's limits; or "physical": m/s and rad/s), `control_hz`
(steps per simulated second), `timing` ("lockstep" | "latency"),
`extra_latency_ms`, `fixed_inference_ms`, `start` (metres or "random"), `laps`, `timeout_s`,
`stop_off_road`, `trapped_s`, `walls`; and Gymnasium's own (`render_mode`, `max_episode_steps`...).
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pilotlab.errors import PilotlabError

ENV_ID = "pilotlab/FollowLine-v0"


def camera_spec(camera: Any):
    """A CameraSpec from what a `make` keyword may say (see the module docstring)."""
    from pilotlab.sim.camera import CameraSpec
    if camera is None or isinstance(camera, CameraSpec):
        return camera
    if camera == "crop":
        return CameraSpec.crop()
    if isinstance(camera, Mapping):
        unknown = sorted(set(camera) - set(CameraSpec.__dataclass_fields__))
        if unknown:
            raise PilotlabError(f"camera: no field(s) {', '.join(unknown)}; CameraSpec has: "
                                f"{', '.join(CameraSpec.__dataclass_fields__)}")
        return CameraSpec(**camera)
    if isinstance(camera, (tuple, list)) and len(camera) == 2 and all(isinstance(c, int) for c in camera):
        return CameraSpec(width=camera[0], height=camera[1])
    raise PilotlabError(f"camera {camera!r}: give (width, height), a dict of CameraSpec fields, 'crop' or None")


def make_follow_line(circuit: str | None = None, direction: str = "cw", camera: Any = (640, 480),
                     renderer: str = "ground", control_hz: float = 20.0, actions: str = "normalized",
                     **options: Any):
    """The entry point `gymnasium.make` calls: a DrivingEnv from the keywords. Actions are normalized
    by default (what Gymnasium's checker and learning libraries expect); `info["command"]` is the
    (v, w) applied, in m/s and rad/s. The circuit is simple_circuit unless a `world` (whose circuit is
    its own) is given."""
    from pilotlab.sim.env import DrivingEnv
    if circuit is None and options.get("world") is None:
        circuit = "simple_circuit"
    if not control_hz > 0:
        raise PilotlabError(f"control_hz must be positive, got {control_hz}")
    return DrivingEnv(circuit, direction=direction, camera=_within_limits(camera_spec(camera)), renderer=renderer,
                      control_period=1.0 / control_hz, actions=actions, **options)


def _within_limits(spec):
    """A camera no larger than a recipe's may be (an image of 100000×100000 is 30 GB)."""
    from annotated_types import Le
    from pilotlab.specs.base import CameraSize
    limit = next(m.le for m in CameraSize.model_fields["width"].metadata if isinstance(m, Le))
    if spec is not None and max(spec.width, spec.height) > limit:
        raise PilotlabError(f"camera {spec.width}×{spec.height} is too large: at most {limit} pixels a side "
                            "(as in a recipe's camera)")
    return spec


def register() -> None:
    import gymnasium
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(ENV_ID, entry_point="pilotlab.sim.follow_line:make_follow_line")
