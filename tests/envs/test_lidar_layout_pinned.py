"""``sb3_adc/LidarObstacleCourse-v1``'s procedural layouts and their pybullet world, pinned to the values they had.

``data/lidar_layout_pinned.json`` was recorded from the code as it was before procedural resets were made fast
(bodies reused across resets, the layout's checks vectorised): for the layout seeds 0 to 4, the course's geometry
(walls, obstacles, start, corridor), a fan of probe rays cast in its pybullet world from a few points of the centre
line, and the first steps of an episode under a fixed steering sequence (observations, ids of what the rays met,
collisions). Large arrays are kept as the SHA-256 of their float64 bytes rounded to 1e-9 (little-endian, C order:
numpy's vectorised sin and cos differ in the last bit from one CPU to another), small ones as numbers (JSON keeps a
float exactly). Every value must come out the same (floats to 1e-9), whatever the environment did
before: a fresh environment, or one that has driven other layouts first.

Regenerate the data (only when a layout or the world changes on purpose, with a version bump)::

    python tests/envs/test_lidar_layout_pinned.py
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet
import pytest

import sb3_adc_envs  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv, simulation
from sb3_adc_envs.lidar_course.simulation import SENSOR_HEIGHT

FIXTURE = Path(__file__).resolve().parent / "data" / "lidar_layout_pinned.json"
#: The pinned layout seeds.
LAYOUT_SEEDS = (0, 1, 2, 3, 4)
#: Obstacle shapes, as codes in the data.
SHAPES = ("box", "cylinder", "wall")
#: Probe rays: this many directions around each probe point, cast at the lidar's height.
N_PROBE_RAYS = 72
#: Probe points: the centre line's vertices at these fractions of its length (by index).
PROBE_FRACTIONS = (0.0, 0.25, 0.5, 0.75)
#: Steps of the pinned episode (fewer where the robot collides first).
N_STEPS = 80


def digest(values: Any, decimals: int = 9) -> str:
    """SHA-256 of an array's float64 values rounded to ``decimals`` (little-endian, C order), the same on every CPU."""
    rounded = np.round(np.asarray(values, dtype=float), decimals) + 0.0  # + 0.0: -0.0 and 0.0 hash the same
    return hashlib.sha256(np.ascontiguousarray(rounded, dtype="<f8").tobytes()).hexdigest()


def steering() -> np.ndarray:
    """The fixed ``(N_STEPS, 1)`` steering sequence: gentle random steering, so that episodes last a while."""
    return np.random.default_rng(61).uniform(-0.3, 0.3, (N_STEPS, 1)).astype(np.float32)


def probe(core: LidarObstacleCourseEnv) -> dict[str, Any]:
    """Cast :data:`N_PROBE_RAYS` rays from each probe point of the centre line in the course's pybullet world."""
    centerline = core.course.corridor.centerline  # type: ignore[union-attr]
    angles = 2.0 * math.pi * np.arange(N_PROBE_RAYS) / N_PROBE_RAYS
    fractions = []
    for fraction in PROBE_FRACTIONS:
        x, y = (float(value) for value in centerline[int(fraction * len(centerline))])
        ray_from = [[x, y, SENSOR_HEIGHT]] * N_PROBE_RAYS
        ray_to = [[x + 5.0 * math.cos(a), y + 5.0 * math.sin(a), SENSOR_HEIGHT] for a in angles]
        # The lidar's filter: walls and obstacles, not the robot.
        hits = pybullet.rayTestBatch(ray_from, ray_to, collisionFilterMask=1, physicsClientId=core.simulation.client_id)
        fractions.append([hit[2] for hit in hits])
    return {"fractions": digest(fractions), "first_fractions": fractions[0][:12], "last_fractions": fractions[-1][-12:]}


def layout_record(core: LidarObstacleCourseEnv) -> dict[str, Any]:
    """The course the environment holds, and probes of its pybullet world."""
    course = core.course
    assert course.corridor is not None
    obstacles = [[SHAPES.index(o.shape), o.x, o.y, o.length, o.width, o.yaw] for o in course.obstacles]
    return {
        "name": course.name,
        "n_walls": len(course.walls),
        "walls": digest(course.walls),
        "first_wall": course.walls[0].tolist(),
        "last_wall": course.walls[-1].tolist(),
        "wall_thickness": course.wall_thickness,
        "centerline": digest(course.corridor.centerline),
        "n_centerline": len(course.corridor.centerline),
        "width": course.corridor.width,
        "obstacles": obstacles,
        "start": [course.start.x, course.start.y, course.start.heading],
        "wall_ids": [len(core.simulation.wall_ids), *core.simulation.wall_ids[:1]],
        "obstacle_ids": list(core.simulation.obstacle_ids),
        "probe": probe(core),
    }


def episode_record(env: gym.Env[np.ndarray, np.ndarray]) -> dict[str, Any]:
    """Steps of :func:`steering` from the current reset until a collision or :data:`N_STEPS`."""
    core: LidarObstacleCourseEnv = env.unwrapped  # type: ignore[assignment]
    simulation = core.simulation
    observations = [core._lidar.astype(float).tolist()]
    ray_bodies = [list(simulation.ray_bodies)]
    touched: list[list[int]] = []
    collisions = []
    for action in steering():
        observation, _, terminated, truncated, info = env.step(action)
        observations.append(observation.astype(float).tolist())
        ray_bodies.append(list(simulation.ray_bodies))
        collisions.append(bool(info["collision"]))
        if terminated or truncated:
            touched.append(sorted(simulation.touched_bodies(*core.pose[:2])))
            break
    return {
        "first_observation": observations[0],
        "observations": digest(observations, decimals=6),  # float32 values: 1e-6
        "last_observation": observations[-1],
        "ray_bodies": ray_bodies,
        "collisions": collisions,
        "touched": touched,
        "pose": list(core.pose),
    }


def record_seed(env: gym.Env[np.ndarray, np.ndarray], layout_seed: int) -> dict[str, Any]:
    """The layout ``layout_seed`` in ``env``, and an episode on it from its start."""
    env.reset(seed=layout_seed, options={"layout_seed": layout_seed})
    core: LidarObstacleCourseEnv = env.unwrapped  # type: ignore[assignment]
    assert core.layout_seed == layout_seed
    record = layout_record(core)
    # reset() again, without jitter: the same start pose; the probes left the robot where it was.
    env.reset(options={"layout_seed": layout_seed})
    record["episode"] = episode_record(env)
    return record


def make_env() -> gym.Env[np.ndarray, np.ndarray]:
    """``sb3_adc/LidarObstacleCourse-v1`` as shipped."""
    return gym.make("sb3_adc/LidarObstacleCourse-v1")


def drawn_layout_seeds() -> list[int]:
    """The layout seeds ``reset(seed=k)`` draws in a fresh environment, for each ``k`` of :data:`LAYOUT_SEEDS`."""
    env = make_env()
    drawn = []
    for seed in LAYOUT_SEEDS:
        env.reset(seed=seed)
        drawn.append(int(env.unwrapped.layout_seed))  # type: ignore[attr-defined]
    env.close()
    return drawn


def regenerate() -> None:
    """Write :data:`FIXTURE` from the environment as it is now, each seed in a fresh environment."""
    data: dict[str, Any] = {}
    for layout_seed in LAYOUT_SEEDS:
        env = make_env()
        data[str(layout_seed)] = record_seed(env, layout_seed)
        env.close()
    data["drawn_layout_seeds"] = drawn_layout_seeds()
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    # One line per layout seed: small, and a diff names the seed.
    FIXTURE.write_text("{\n" + ",\n".join(f"{json.dumps(key)}: {json.dumps(value)}" for key, value in data.items()) + "\n}\n")


@pytest.fixture(scope="module", name="expected")
def expected_data() -> dict[str, Any]:
    """The recorded data."""
    return json.loads(FIXTURE.read_text())


def assert_same(actual: dict[str, Any], expected: dict[str, Any], where: str) -> None:
    """Equal key by key, floats to 1e-9 (the last bit of numpy's sin and cos depends on the CPU), the rest exactly."""
    actual = json.loads(json.dumps(actual))
    assert actual.keys() == expected.keys(), where
    for key in expected:
        if key == "episode":
            assert_same_rays(actual[key].pop("ray_bodies"), expected[key]["ray_bodies"], where)
            expected = {**expected, key: {k: v for k, v in expected[key].items() if k != "ray_bodies"}}
        assert close(actual[key], expected[key]), f"{where}: {key}: {actual[key]} != {expected[key]}"


def assert_same_rays(actual: list[list[int]], expected: list[list[int]], where: str) -> None:
    """
    The bodies each ray met, equal but for a few rays that end where two bodies meet (the same distance either way:
    which one pybullet reports then depends on the CPU's last bit). 1 ray in 200 at most.
    """
    assert list(map(len, actual)) == list(map(len, expected)), where
    n_rays = sum(map(len, expected))
    differing = sum(a != e for row_a, row_e in zip(actual, expected, strict=True) for a, e in zip(row_a, row_e, strict=True))
    assert differing <= n_rays // 200, f"{where}: {differing} of {n_rays} rays met other bodies"


def close(actual: Any, expected: Any) -> bool:
    """Nested lists and dicts equal, floats to 1e-9."""
    if isinstance(expected, float) and isinstance(actual, float | int):
        return math.isclose(actual, expected, rel_tol=1e-9, abs_tol=1e-9)
    if isinstance(expected, list) and isinstance(actual, list):
        return len(actual) == len(expected) and all(map(close, actual, expected))
    if isinstance(expected, dict) and isinstance(actual, dict):
        return actual.keys() == expected.keys() and all(close(actual[k], expected[k]) for k in expected)
    return bool(actual == expected)


@pytest.mark.parametrize("layout_seed", LAYOUT_SEEDS)
def test_a_fresh_environment_builds_the_pinned_layout(expected: dict[str, Any], layout_seed: int) -> None:
    env = make_env()
    actual = record_seed(env, layout_seed)
    env.close()
    assert_same(actual, expected[str(layout_seed)], f"layout seed {layout_seed}")


def test_reset_draws_the_pinned_layout_seeds(expected: dict[str, Any]) -> None:
    assert drawn_layout_seeds() == expected["drawn_layout_seeds"]


def test_consecutive_resets_give_what_fresh_environments_give(expected: dict[str, Any]) -> None:
    # One environment through the pinned layouts in an order that grows and shrinks the world, one repeated back
    # to back, with layouts drawn by reset(seed=k) in between: each must be what a fresh environment gives.
    env = make_env()
    order = (3, 0, 4, 4, 1, 2, 0, 3)
    for i, layout_seed in enumerate(order):
        actual = record_seed(env, layout_seed)
        assert_same(actual, expected[str(layout_seed)], f"reset {i} (layout seed {layout_seed})")
        for seed in range(10 * i, 10 * i + 3):
            env.reset(seed=seed)
            env.step(np.zeros(1, dtype=np.float32))
    env.close()


@pytest.mark.parametrize("robot", ["kinematic", "wheeled"])
@pytest.mark.parametrize("rays_per_reading", [1, 4])
@pytest.mark.parametrize("reset_world_every", [None, 1, 3])
def test_consecutive_resets_match_fresh_environments_episode_by_episode(
    monkeypatch: pytest.MonkeyPatch, robot: str, rays_per_reading: int, reset_world_every: int | None
) -> None:
    # Any sequence of layout seeds: an environment that drove others first gives each one's episode exactly as a
    # fresh environment does (the reused world keeps nothing of the layouts before), whether or not its world was
    # emptied in between (every RESET_WORLD_EVERY courses; None: as shipped).
    if reset_world_every is not None:
        monkeypatch.setattr(simulation, "RESET_WORLD_EVERY", reset_world_every)
    seeds = (7, 123_456, 7, 42, 999_999, 5, 0, 2_000_001, 13)
    kwargs: dict[str, Any] = {"robot": robot, "rays_per_reading": rays_per_reading}
    env = gym.make("sb3_adc/LidarObstacleCourse-v1", **kwargs)
    reused = []
    for layout_seed in seeds:
        env.reset(options={"layout_seed": layout_seed})
        reused.append(episode_record(env))
    env.close()
    for layout_seed, actual in zip(seeds, reused, strict=True):
        fresh_env = gym.make("sb3_adc/LidarObstacleCourse-v1", **kwargs)
        fresh_env.reset(options={"layout_seed": layout_seed})
        fresh = episode_record(fresh_env)
        fresh_env.close()
        assert_same(actual, json.loads(json.dumps(fresh)), f"{kwargs}, layout seed {layout_seed}")


def test_the_shapes_of_past_layouts_are_freed() -> None:
    # pybullet frees collision shapes only when the world is emptied, every RESET_WORLD_EVERY layouts: shape ids
    # (handles, numbered from 0 in an empty world) stay bounded however many layouts the environment goes through.
    env = make_env()
    core: LidarObstacleCourseEnv = env.unwrapped  # type: ignore[assignment]
    most_parts = 0
    for seed in range(5 * simulation.RESET_WORLD_EVERY):
        env.reset(seed=seed)
        most_parts = max(most_parts, len(core.course.walls) + len(core.course.obstacles))
    client = core.simulation.client_id
    shape = pybullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=0.1, physicsClientId=client)
    assert shape <= (simulation.RESET_WORLD_EVERY + 1) * most_parts + 1
    assert pybullet.getNumBodies(physicsClientId=client) <= 1 + -(-most_parts // simulation.LINKS_PER_BODY)
    env.close()


if __name__ == "__main__":
    regenerate()
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size / 1024:.0f} KiB)")
