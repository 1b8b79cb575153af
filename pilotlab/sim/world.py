"""The pybullet world: flat ground, the road and its red centre line as meshes, optional walls.

pybullet runs in DIRECT mode (no display, no GUI); each World has its own physics client, so several
can live in one process. The ground is a collision plane with no mesh (renderers paint grass where
nothing else is drawn); the road and the line are visual-only meshes lying on it.
"""
from __future__ import annotations

import math
import weakref

import numpy as np

from pilotlab.circuits.circuit import Circuit
from pilotlab.sim.bullet import p
from pilotlab.sim.camera import LINE, LINE_WIDTH_M, ROAD, WALL

GROUND_FRICTION = 1.0
# 240 Hz with pybullet's 50 solver iterations costs ~0.3 ms per 1/240 s here; 120 Hz with 20 iterations
# drives the same laps (the expert's mean distance to the line changes by < 1 cm) at a third of the cost.
PHYSICS_HZ = 120.0
SOLVER_ITERATIONS = 20
CHUNK_POINTS = 400          # centreline points per mesh (pybullet limits the vertices of one mesh)
# The line lies exactly on the ground (as the ground renderer draws it); the road 3 mm below it, so
# that the line is never hidden by the road, even where two stretches of road overlap.
ROAD_SINK_M = 0.003
WALL_HEIGHT_M, WALL_THICKNESS_M, WALL_GAP_M = 0.6, 0.3, 0.5
WALL_BOXES_PER_BODY = 16  # pybullet crashes on shape arrays of more than about 20


def _rgba(rgb) -> list[float]:
    return [c / 255 for c in rgb] + [1.0]


def strip_mesh(left: np.ndarray, right: np.ndarray, z: float) -> tuple[list, list]:
    """Vertices and triangle indices of a band between two polylines of equal length (open)."""
    count = len(left)
    vertices = np.concatenate([np.column_stack([left, np.full(count, z)]),
                               np.column_stack([right, np.full(count, z)])])
    i = np.arange(count - 1)
    # Two triangles per quad, counter-clockwise seen from above for a band driven along +arc.
    triangles = np.stack([i, count + i, count + i + 1, i, count + i + 1, i + 1], axis=1)
    return vertices.tolist(), triangles.reshape(-1).tolist()


def mesh_points(circuit: Circuit, max_turn: float = 0.02, max_step: float = 2.0) -> np.ndarray:
    """Indices of the centreline points to keep as mesh vertices: a new one whenever the heading has
    turned by `max_turn` radians or `max_step` metres have passed since the last one."""
    turns = np.abs(circuit.curvature) * (circuit.length / len(circuit.points))
    kept, turned, travelled = [0], 0.0, 0.0
    for i in range(1, len(circuit.points)):
        turned, travelled = turned + turns[i], travelled + circuit.length / len(circuit.points)
        if turned >= max_turn or travelled >= max_step:
            kept.append(i)
            turned, travelled = 0.0, 0.0
    return np.array(kept)


class World:
    """A pybullet physics client holding the ground, one circuit's road, and optionally walls."""

    def __init__(self, circuit: Circuit, *, walls: bool = False, physics_hz: float = PHYSICS_HZ,
                 solver_iterations: int = SOLVER_ITERATIONS, road_meshes: bool = True):
        self.circuit, self.walls, self.physics_hz = circuit, walls, physics_hz
        self.client = p.connect(p.DIRECT)
        # an env dropped without close() kept its client, and its memory, until the process ended (an outside
        # test: 40 dropped envs, 41 clients, 300 MB): the client goes with the World
        self._disconnect = weakref.finalize(self, p.disconnect, physicsClientId=self.client)
        p.resetSimulation(physicsClientId=self.client)
        p.setPhysicsEngineParameter(fixedTimeStep=1.0 / physics_hz, numSubSteps=0, deterministicOverlappingPairs=1,
                                    numSolverIterations=solver_iterations, physicsClientId=self.client)
        p.setGravity(0, 0, -9.81, physicsClientId=self.client)
        self._add_ground()
        if road_meshes:  # only pybullet's renderer needs them
            self._add_road()
        if walls:
            self._add_walls()

    def close(self) -> None:
        if self.client is not None:
            self._disconnect()
            self.client = None

    def remove(self, body: int) -> None:
        p.removeBody(body, physicsClientId=self.client)

    def step(self, count: int) -> None:
        for _ in range(count):
            p.stepSimulation(physicsClientId=self.client)

    def _add_ground(self) -> None:
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=self.client)
        # Without a visual shape pybullet would draw the plane's checkerboard: give it a speck far below.
        speck = p.createVisualShape(p.GEOM_SPHERE, radius=1e-3, visualFramePosition=[0, 0, -100],
                                    physicsClientId=self.client)
        self.ground = p.createMultiBody(0, plane, speck, [0, 0, 0], physicsClientId=self.client)
        p.changeDynamics(self.ground, -1, lateralFriction=GROUND_FRICTION, rollingFriction=0.0,
                         spinningFriction=0.0, physicsClientId=self.client)

    def _add_road(self) -> None:
        """Road and line bands as meshes, with vertices only where the line bends (TinyRenderer's cost
        grows with the triangle count): a chord then strays less than 1 cm from the line."""
        circuit, half_line = self.circuit, LINE_WIDTH_M / 2
        kept = mesh_points(circuit)
        bands = ((circuit.road_width / 2, -circuit.road_width / 2, -ROAD_SINK_M, ROAD),
                 (half_line, -half_line, 0.0, LINE))
        for start in range(0, len(kept), CHUNK_POINTS):
            index = kept[np.arange(start, min(start + CHUNK_POINTS, len(kept)) + 1) % len(kept)]
            for left, right, z, colour in bands:
                vertices, triangles = strip_mesh(circuit.offset_line(left)[index], circuit.offset_line(right)[index], z)
                shape = p.createVisualShape(p.GEOM_MESH, vertices=vertices, indices=triangles, rgbaColor=_rgba(colour),
                                            physicsClientId=self.client)
                p.createMultiBody(0, -1, shape, [0, 0, 0], physicsClientId=self.client)

    def _add_walls(self) -> None:
        """Boxes along both road edges, WALL_GAP_M outside them: a car that leaves the road hits them."""
        circuit = self.circuit
        offset = circuit.road_width / 2 + WALL_GAP_M + WALL_THICKNESS_M / 2
        for side in (offset, -offset):
            line = circuit.offset_line(side)[::8]  # a box every ~2 m
            ends = np.roll(line, -1, axis=0)
            boxes = [((a + b) / 2, b - a) for a, b in zip(line, ends) if np.linalg.norm(b - a) > 1e-3]
            for first in range(0, len(boxes), WALL_BOXES_PER_BODY):
                self._add_wall_body(boxes[first:first + WALL_BOXES_PER_BODY])

    def _add_wall_body(self, boxes: list) -> None:
        half = [[np.linalg.norm(d) / 2 + 0.05, WALL_THICKNESS_M / 2, WALL_HEIGHT_M / 2] for _, d in boxes]
        positions = [[c[0], c[1], WALL_HEIGHT_M / 2] for c, _ in boxes]
        orientations = [p.getQuaternionFromEuler([0, 0, math.atan2(d[1], d[0])]) for _, d in boxes]
        kinds = [p.GEOM_BOX] * len(boxes)
        collision = p.createCollisionShapeArray(kinds, halfExtents=half, collisionFramePositions=positions,
                                                collisionFrameOrientations=orientations, physicsClientId=self.client)
        visual = p.createVisualShapeArray(kinds, halfExtents=half, visualFramePositions=positions,
                                          visualFrameOrientations=orientations,
                                          rgbaColors=[_rgba(WALL)] * len(boxes), physicsClientId=self.client)
        p.createMultiBody(0, collision, visual, [0, 0, 0], physicsClientId=self.client)
