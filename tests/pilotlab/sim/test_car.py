import pybullet as p
import pytest

from pilotlab.circuits.load import get_circuit
from pilotlab.sim.car import Car, CarSpec
from pilotlab.sim.world import World


@pytest.fixture
def world(stadium_csv):
    world = World(get_circuit(stadium_csv), road_meshes=False)
    yield world
    world.close()


def drive(world, car, v, w, seconds):
    car.apply(v, w)
    world.step(round(seconds * world.physics_hz))
    return car.state()


def test_the_car_accelerates_with_limited_torque_then_holds_the_commanded_speed(world):
    car = Car(world.client, CarSpec(), (0.0, 0.0, 0.0))
    _, _, speed, _ = drive(world, car, 10.0, 0.0, 1.0)
    assert 3.0 < speed < 6.0  # about 4.4 m/s² from the rear wheels' torque: no teleporting
    position, orientation, speed, yaw_rate = drive(world, car, 10.0, 0.0, 3.0)
    assert speed == pytest.approx(10.0, abs=0.05) and abs(yaw_rate) < 1e-3
    assert position[2] == pytest.approx(CarSpec().wheel_radius, abs=0.01)  # on its wheels
    assert abs(position[1]) < 0.05  # straight ahead, along +x


def test_steering_turns_the_car_at_the_commanded_rate_within_the_tyres_grip(world):
    car = Car(world.client, CarSpec(), (0.0, 0.0, 0.0), speed=8.0)
    _, _, speed, yaw_rate = drive(world, car, 8.0, 0.5, 2.0)
    assert speed == pytest.approx(8.0, abs=0.1) and yaw_rate == pytest.approx(0.5, abs=0.03)
    left, right = car.steering_angles(8.0, 0.5)
    assert left > right > 0  # Ackermann: the inner (left) wheel turns more
    assert car.steering_angles(8.0, 50.0) == (CarSpec().max_steer, pytest.approx(0.5, abs=0.1))


def test_asking_for_more_than_the_grip_allows_makes_the_car_slide(world):
    car = Car(world.client, CarSpec(), (0.0, 0.0, 0.0), speed=12.0)
    _, orientation, speed, yaw_rate = drive(world, car, 12.0, 2.0, 2.0)  # 24 m/s² asked, ~12 possible
    assert speed < 10.0 or abs(yaw_rate - 2.0) > 0.3


def test_braking_uses_all_wheels(world):
    car = Car(world.client, CarSpec(), (0.0, 0.0, 0.0), speed=10.0)
    _, _, speed, _ = drive(world, car, 0.0, 0.0, 0.5)
    deceleration = (10.0 - speed) / 0.5
    assert 6.0 < deceleration < 10.0


def test_each_world_is_its_own_pybullet_client(stadium_csv):
    first, second = World(get_circuit(stadium_csv)), World(get_circuit(stadium_csv))
    try:
        assert first.client != second.client
        assert p.getNumBodies(physicsClientId=first.client) == p.getNumBodies(physicsClientId=second.client) > 1
    finally:
        first.close()
        second.close()
