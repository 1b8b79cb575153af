"""The car: a small Formula-1-like car with four wheels, Ackermann steering and rear-wheel drive.

Sizes are those of a small single-seater (about a Formula 4 scaled to 2/3): 2.6 m long, 1.0 m track,
1.6 m wheelbase, 0.25 m wheels, 180 kg. The URDF is generated from `CarSpec`, so the controller's
geometry always matches the model. Commands (v m/s, w rad/s) become, as on the JdeRobot F1 car,
a steering angle from the bicycle model, `atan(w * wheelbase / v)`, split into Ackermann angles,
and rear wheel speeds with the differential of a car turning at rate w. pybullet's motors then
apply them with limited torque and steering rate, and the tyres grip with limited friction, so the
car lags, slides and understeers like a real one.
"""
from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass

from pilotlab.sim.bullet import p

REVERSE_SPEED = 5.0  # m/s: the fastest a command may drive backwards


@dataclass(frozen=True)
class CarSpec:
    wheelbase: float = 1.6
    track: float = 1.0
    wheel_radius: float = 0.25
    wheel_width: float = 0.2
    wheel_mass: float = 8.0
    body_length: float = 2.6
    body_width: float = 0.7
    body_height: float = 0.3
    body_mass: float = 148.0
    max_steer: float = 0.6            # rad, per front wheel
    steer_rate: float = 4.0           # rad/s
    drive_torque: float = 110.0       # N·m per rear wheel: accelerates at about 4.4 m/s²
    brake_torque: float = 80.0        # N·m per front wheel, added when slowing: about 8 m/s² in all
    tyre_friction: float = 1.2
    max_speed: float = 25.0           # m/s, commands are clipped to [-REVERSE_SPEED, max_speed]
    version: int = 1

    @property
    def command_bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((v_min, v_max), (w_min, w_max)) of the commands that mean something to this car: v as
        clipped by `Car.apply`; beyond |w| = max_speed · tan(max_steer) / wheelbase the steering is at
        its stop at every speed the car can reach, and `Car.apply` clips w there too."""
        w_max = self.max_speed * math.tan(self.max_steer) / self.wheelbase
        return (-REVERSE_SPEED, self.max_speed), (-w_max, w_max)

    def urdf(self) -> str:
        """The car as URDF text: base_link is the chassis, centred between the axles at axle height."""
        half, floor = self.wheelbase / 2, 0.05  # the chassis floor is 5 cm above the axles
        body = (self.body_length, self.body_width, self.body_height)
        wheels = "".join(self._wheel(name, x, y) for name, x, y in (
            ("rear_left", -half, self.track / 2), ("rear_right", -half, -self.track / 2)))
        steered = "".join(self._steered_wheel(name, half, y) for name, y in (
            ("front_left", self.track / 2), ("front_right", -self.track / 2)))
        visuals = "".join(_box_visual(xyz, size, rgba) for xyz, size, rgba in (
            ((0, 0, floor + self.body_height / 2), body, "0.8 0.05 0.05 1"),                        # monocoque
            ((half + 0.45, 0, floor + 0.05), (0.25, self.track + self.wheel_width, 0.05), "0.1 0.1 0.1 1"),  # front wing
            ((-half - 0.35, 0, floor + 0.6), (0.3, self.track, 0.05), "0.1 0.1 0.1 1")))            # rear wing
        return f"""<?xml version="1.0"?>
<robot name="pilotlab_f1">
  <link name="base_link">
    {_inertial(self.body_mass, _box_inertia(self.body_mass, *body))}{visuals}
    <collision><origin xyz="0 0 {floor + self.body_height / 2:.3f}"/>
      <geometry><box size="{' '.join(map(str, body))}"/></geometry></collision>
  </link>{wheels}{steered}
</robot>
"""

    def _wheel_link(self, name: str) -> str:
        """A wheel: a cylinder to look at, a sphere to roll on (pybullet's cylinder contacts chatter)."""
        m, r, w = self.wheel_mass, self.wheel_radius, self.wheel_width
        side = m * (3 * r * r + w * w) / 12
        return f"""
  <link name="{name}_wheel">
    {_inertial(m, (side, m * r * r / 2, side))}
    <visual><origin rpy="1.5708 0 0"/><geometry><cylinder radius="{r}" length="{w}"/></geometry>
      <material name="tyre"><color rgba="0.05 0.05 0.05 1"/></material></visual>
    <collision><geometry><sphere radius="{r}"/></geometry></collision>
  </link>"""

    def _wheel(self, name: str, x: float, y: float) -> str:
        return self._wheel_link(name) + f"""
  <joint name="{name}_axle" type="continuous"><parent link="base_link"/><child link="{name}_wheel"/>
    <origin xyz="{x} {y} 0"/><axis xyz="0 1 0"/></joint>"""

    def _steered_wheel(self, name: str, x: float, y: float) -> str:
        return f"""
  <link name="{name}_knuckle">
    {_inertial(1.0, (0.01, 0.01, 0.01))}
  </link>
  <joint name="{name}_steer" type="revolute"><parent link="base_link"/><child link="{name}_knuckle"/>
    <origin xyz="{x} {y} 0"/><axis xyz="0 0 1"/>
    <limit lower="{-self.max_steer}" upper="{self.max_steer}" effort="5000" velocity="{self.steer_rate}"/></joint>""" \
            + self._wheel_link(name) + f"""
  <joint name="{name}_axle" type="continuous"><parent link="{name}_knuckle"/><child link="{name}_wheel"/>
    <origin xyz="0 0 0"/><axis xyz="0 1 0"/></joint>"""


def _box_inertia(mass: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    return mass * (y * y + z * z) / 12, mass * (x * x + z * z) / 12, mass * (x * x + y * y) / 12


def _inertial(mass: float, diagonal: tuple[float, float, float]) -> str:
    ixx, iyy, izz = diagonal
    return (f'<inertial><mass value="{mass}"/><inertia ixx="{ixx:.4f}" iyy="{iyy:.4f}" izz="{izz:.4f}" '
            'ixy="0" ixz="0" iyz="0"/></inertial>')


def _box_visual(xyz, size, rgba: str) -> str:
    return (f'\n    <visual><origin xyz="{" ".join(f"{v:.3f}" for v in xyz)}"/>'
            f'<geometry><box size="{" ".join(f"{v:.3f}" for v in size)}"/></geometry>'
            f'<material name="c{rgba.replace(" ", "_").replace(".", "")}"><color rgba="{rgba}"/></material></visual>')


def scaled_car(scale: float, max_speed: float) -> CarSpec:
    """pilotlab's car at `scale` with the same accelerations: lengths × s, masses × s³, torques × s⁴."""
    base = CarSpec()
    return CarSpec(wheelbase=base.wheelbase * scale, track=base.track * scale, wheel_radius=base.wheel_radius * scale,
                   wheel_width=base.wheel_width * scale, wheel_mass=base.wheel_mass * scale**3,
                   body_length=base.body_length * scale, body_width=base.body_width * scale,
                   body_height=base.body_height * scale, body_mass=base.body_mass * scale**3,
                   drive_torque=base.drive_torque * scale**4, brake_torque=base.brake_torque * scale**4,
                   max_speed=max_speed)


# BehaviorMetrics' F1 is the Renault mesh at scale 0.2 (about 1 m long): in BM's worlds, whose 3.4 m road is
# walled at its edge, the car is that size (pilotlab's 2.6 m car hit the walls where a small one passes).
BM_F1 = scaled_car(0.4, max_speed=10.0)


class Car:
    """A car loaded in a pybullet world, driven by (v, w) commands."""

    def __init__(self, client: int, spec: CarSpec, pose: tuple[float, float, float], speed: float = 0.0):
        self.client, self.spec = client, spec
        x, y, yaw = pose
        with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as handle:
            handle.write(spec.urdf())
        try:
            self.body = p.loadURDF(handle.name, [x, y, spec.wheel_radius], p.getQuaternionFromEuler([0, 0, yaw]),
                                   flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
        finally:
            os.unlink(handle.name)
        joints = {p.getJointInfo(self.body, j, physicsClientId=client)[1].decode(): j
                  for j in range(p.getNumJoints(self.body, physicsClientId=client))}
        self.steer = (joints["front_left_steer"], joints["front_right_steer"])
        self.drive = (joints["rear_left_axle"], joints["rear_right_axle"])
        self.free = (joints["front_left_axle"], joints["front_right_axle"])
        self._set_dynamics()
        if speed:
            p.resetBaseVelocity(self.body, [speed * math.cos(yaw), speed * math.sin(yaw), 0], [0, 0, 0],
                                physicsClientId=client)
            for joint in self.drive + self.free:
                p.resetJointState(self.body, joint, 0.0, speed / spec.wheel_radius, physicsClientId=client)
        self.command = (0.0, 0.0)
        self.apply(speed, 0.0)


    def hide(self) -> None:
        """Make every link invisible to the renderers (a camera inside the body must see out)."""
        for link in range(-1, p.getNumJoints(self.body, physicsClientId=self.client)):
            p.changeVisualShape(self.body, link, rgbaColor=[0, 0, 0, 0], physicsClientId=self.client)
    def _set_dynamics(self) -> None:
        client, body = self.client, self.body
        p.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=client)
        for joint in self.drive + self.free:  # (damping arguments here would make pybullet ignore the call)
            p.changeDynamics(body, joint, lateralFriction=self.spec.tyre_friction, rollingFriction=0.0,
                             spinningFriction=0.0, physicsClientId=client)

    def steering_angles(self, v: float, w: float) -> tuple[float, float]:
        """Left and right front wheel angles (rad) that turn the car at rate w when driving at v."""
        spec = self.spec
        if abs(v) < 0.05 or abs(w) < 1e-6:
            return 0.0, 0.0
        radius = v / w  # signed: + turning left
        centre = math.atan(spec.wheelbase / radius)
        centre = max(-spec.max_steer, min(spec.max_steer, centre))
        radius = spec.wheelbase / math.tan(centre)
        left = math.atan(spec.wheelbase / (radius - spec.track / 2))
        right = math.atan(spec.wheelbase / (radius + spec.track / 2))
        clip = spec.max_steer
        return max(-clip, min(clip, left)), max(-clip, min(clip, right))

    def apply(self, v: float, w: float, speed: float | None = None) -> None:
        """Set the command in force until the next one: steering targets and wheel speeds. The rear
        wheels drive (and brake); the front wheels roll freely, and brake too when the car must slow.
        `speed`: the forward speed now, when the caller has just read it (saves reading it again)."""
        spec, client, body = self.spec, self.client, self.body
        (v_min, v_max), (w_min, w_max) = spec.command_bounds
        v = max(v_min, min(v_max, float(v)))
        w = max(w_min, min(w_max, float(w)))   # the rear wheels' speed difference follows w: past the stop, nothing more
        self.command = (v, w)
        for joint, angle in zip(self.steer, self.steering_angles(v, w)):
            p.setJointMotorControl2(body, joint, p.POSITION_CONTROL, targetPosition=angle, force=5000,
                                    maxVelocity=spec.steer_rate, physicsClientId=client)
        for joint, side in zip(self.drive, (-1.0, 1.0)):
            wheel_speed = (v + side * w * spec.track / 2) / spec.wheel_radius
            p.setJointMotorControl2(body, joint, p.VELOCITY_CONTROL, targetVelocity=wheel_speed,
                                    force=spec.drive_torque, physicsClientId=client)
        braking = abs(v) < abs(self.state()[2] if speed is None else speed) - 0.2
        for joint in self.free:
            p.setJointMotorControl2(body, joint, p.VELOCITY_CONTROL, targetVelocity=v / spec.wheel_radius,
                                    force=spec.brake_torque if braking else 0.0, physicsClientId=client)

    def state(self) -> tuple[tuple[float, float, float], tuple[float, float, float, float], float, float]:
        """(position, orientation quaternion, forward speed m/s, yaw rate rad/s) of the chassis."""
        position, orientation = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        linear, angular = p.getBaseVelocity(self.body, physicsClientId=self.client)
        yaw = p.getEulerFromQuaternion(orientation)[2]
        forward = linear[0] * math.cos(yaw) + linear[1] * math.sin(yaw)
        return position, orientation, forward, angular[2]
