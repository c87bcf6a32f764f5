"""``sb3_adc/LidarObstacleCourse-v1`` reuses its pybullet world across resets: same layouts, same episodes.

``data/lidar_reset_reuse.npz`` holds what the environment gave before its resets reused the pybullet bodies
(recorded when the world was still rebuilt from scratch at every new layout): for both robots and for the
training and held-out layout seeds, a run of resets in one environment (``reset(seed=k)``, a layout seed drawn
again, one repeated back to back and the first one revisited at the end), each followed by up to
:data:`N_STEPS` steps of a fixed steering sequence, and the geometry of every layout met. Reusing bodies must
change none of it: the kinematic robot and the wheeled robot (pybullet is deterministic in the same world)
reproduce it, integers and flags exactly and floats to the last bits that numpy's vectorised sin and cos leave to
the CPU (:func:`assert_same`).

Regenerate the data (only when the environment's semantics change on purpose, with a version bump)::

    python tests/envs/test_lidar_reset_reuse.py
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet
import pytest

import sb3_adc_envs  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv
from sb3_adc_envs.lidar_course.course import Course
from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS, TRAIN_LAYOUT_SEEDS

FIXTURE = Path(__file__).resolve().parent / "data" / "lidar_reset_reuse.npz"
#: Layout seed ranges: the training split and the held-out one.
SPLITS = {"train": TRAIN_LAYOUT_SEEDS, "held_out": TEST_LAYOUT_SEEDS}
ROBOTS = ("kinematic", "wheeled")
#: The ``seed`` of each reset, in order, in one environment: 3 twice in a row (the same layout again), 0 at the end
#: (the first layout, after others).
RESET_SEEDS = (0, 1, 2, 3, 3, 4, 5, 6, 7, 8, 9, 0)
#: Steps after each reset (fewer where the robot collides first).
N_STEPS = 60
#: Obstacle shapes, as codes in the data.
SHAPES = ("box", "cylinder", "wall")


def steering() -> np.ndarray:
    """The fixed ``(N_STEPS, 1)`` steering sequence: a smoothed random walk, so that some episodes last."""
    noise = np.random.default_rng(20_251_205).uniform(-1.0, 1.0, N_STEPS)
    return np.clip(np.convolve(noise, np.ones(4) / 2.0, mode="same"), -1.0, 1.0).astype(np.float32)[:, None]


def make_env(robot: str, split: str) -> gym.Env[np.ndarray, np.ndarray]:
    """``sb3_adc/LidarObstacleCourse-v1`` with a robot, drawing its layouts from a split's layout seeds."""
    return gym.make("sb3_adc/LidarObstacleCourse-v1", robot=robot, layout_seeds=SPLITS[split])


def geometry(course: Course) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A course as arrays: its ``(n, 4)`` walls, ``(m, 6)`` obstacles (shape code, x, y, length, width, yaw), start."""
    obstacles = np.array(
        [[SHAPES.index(o.shape), o.x, o.y, o.length, o.width, o.yaw] for o in course.obstacles], dtype=float
    ).reshape(-1, 6)
    start = np.array([course.start.x, course.start.y, course.start.heading])
    return course.walls, obstacles, start


def record(env: gym.Env[np.ndarray, np.ndarray]) -> dict[str, np.ndarray]:
    """
    Run :data:`RESET_SEEDS`' resets in one environment, each followed by the steering sequence until a collision.

    :return: arrays with one row per reset: ``layout_seed``; ``steps``; ``observation``, ``distance``,
        ``clearance`` and ``pose`` at the reset and after each step (NaN after the episode's end); ``reward``,
        ``terminated``, ``collision`` and ``is_success`` of each step
    """
    n_resets, n_rays = len(RESET_SEEDS), env.observation_space.shape[0]  # type: ignore[index]
    out: dict[str, np.ndarray] = {
        "layout_seed": np.zeros(n_resets, dtype=np.int64),
        "steps": np.zeros(n_resets, dtype=np.int64),
        "observation": np.full((n_resets, N_STEPS + 1, n_rays), np.nan, dtype=np.float32),
        "distance": np.full((n_resets, N_STEPS + 1), np.nan),
        "clearance": np.full((n_resets, N_STEPS + 1), np.nan),
        "pose": np.full((n_resets, N_STEPS + 1, 3), np.nan),
        "reward": np.full((n_resets, N_STEPS), np.nan),
        "terminated": np.zeros((n_resets, N_STEPS), dtype=bool),
        "collision": np.zeros((n_resets, N_STEPS), dtype=bool),
        "is_success": np.zeros((n_resets, N_STEPS), dtype=bool),
    }
    core: LidarObstacleCourseEnv = env.unwrapped  # type: ignore[assignment]

    def keep(i: int, t: int, observation: np.ndarray, info: dict[str, Any]) -> None:
        assert info["course"] == core.course.name
        out["observation"][i, t] = observation
        out["distance"][i, t] = info["distance"]
        out["clearance"][i, t] = info["clearance"]
        out["pose"][i, t] = core.pose

    for i, seed in enumerate(RESET_SEEDS):
        observation, info = env.reset(seed=seed)
        out["layout_seed"][i] = core.layout_seed
        keep(i, 0, observation, info)
        for t, action in enumerate(steering()):
            observation, reward, terminated, truncated, info = env.step(action)
            keep(i, t + 1, observation, info)
            out["reward"][i, t] = reward
            out["terminated"][i, t], out["collision"][i, t], out["is_success"][i, t] = (
                terminated,
                info["collision"],
                info["is_success"],
            )
            out["steps"][i] = t + 1
            if terminated or truncated:
                break
    return out


def regenerate() -> None:
    """Write :data:`FIXTURE` from the environment as it is now."""
    data: dict[str, np.ndarray] = {}
    for split in SPLITS:
        for robot in ROBOTS:
            env = make_env(robot, split)
            for key, value in record(env).items():
                data[f"{robot}/{split}/{key}"] = value
            env.close()
        for layout_seed in np.unique(data[f"kinematic/{split}/layout_seed"]):
            # The same generator draws every layout: regenerating one from its seed gives what the env drove.
            env = make_env("kinematic", split)
            env.reset(options={"layout_seed": int(layout_seed)})
            walls, obstacles, start = geometry(env.unwrapped.course)  # type: ignore[attr-defined]
            env.close()
            data[f"geometry/{split}/{layout_seed}/walls"] = walls
            data[f"geometry/{split}/{layout_seed}/obstacles"] = obstacles
            data[f"geometry/{split}/{layout_seed}/start"] = start
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(FIXTURE, **data)


def assert_same(actual: np.ndarray, expected: np.ndarray, err_msg: str = "") -> None:
    """Equal arrays: floats to 1e-4 (the CPU.s last bit moves a grazing lidar ray by ~2e-6), the rest exactly."""
    if np.issubdtype(expected.dtype, np.floating):
        np.testing.assert_allclose(actual, expected, rtol=0.0, atol=1e-4, err_msg=err_msg)
    else:
        np.testing.assert_array_equal(actual, expected, err_msg=err_msg)


@pytest.fixture(scope="module", name="expected")
def expected_data() -> dict[str, np.ndarray]:
    """The recorded data."""
    with np.load(FIXTURE) as data:
        return dict(data)


@pytest.mark.parametrize("split", list(SPLITS))
def test_layouts_are_the_recorded_ones(expected: dict[str, np.ndarray], split: str) -> None:
    env = make_env("kinematic", split)
    for layout_seed in np.unique(expected[f"kinematic/{split}/layout_seed"]):
        env.reset(options={"layout_seed": int(layout_seed)})
        core: LidarObstacleCourseEnv = env.unwrapped  # type: ignore[assignment]
        walls, obstacles, start = geometry(core.course)
        assert_same(walls, expected[f"geometry/{split}/{layout_seed}/walls"])
        assert_same(obstacles, expected[f"geometry/{split}/{layout_seed}/obstacles"])
        assert_same(start, expected[f"geometry/{split}/{layout_seed}/start"])
        # The pybullet world holds this layout: one body per wall and per obstacle.
        assert len(core.simulation.wall_ids) == len(walls)
        assert len(core.simulation.obstacle_ids) == len(obstacles)
    env.close()


@pytest.mark.parametrize("split", list(SPLITS))
@pytest.mark.parametrize("robot", ROBOTS)
def test_episodes_are_the_recorded_ones(expected: dict[str, np.ndarray], robot: str, split: str) -> None:
    env = make_env(robot, split)
    actual = record(env)
    env.close()
    # The data covers collisions and episodes that last, and the layout repeated back to back.
    assert expected[f"{robot}/{split}/collision"].any()
    assert (expected[f"{robot}/{split}/steps"] == N_STEPS).any()
    for key, value in actual.items():
        assert_same(value, expected[f"{robot}/{split}/{key}"], err_msg=f"{robot}/{split}/{key}")


@pytest.mark.parametrize("robot", ROBOTS)
def test_resets_do_not_add_bodies(robot: str) -> None:
    env = make_env(robot, "train")
    core: LidarObstacleCourseEnv = env.unwrapped  # type: ignore[assignment]
    counts, largest = [], 0
    for seed in range(50):
        env.reset(seed=seed)
        counts.append(pybullet.getNumBodies(physicsClientId=core.simulation.client_id))
        # No more bodies than the robot and one per wall and obstacle of the largest layout met so far.
        largest = max(largest, len(core.course.walls) + len(core.course.obstacles))
        assert counts[-1] <= largest + 1
    env.close()
    assert max(counts[25:]) <= max(counts[:25])


@pytest.mark.parametrize("robot", ROBOTS)
def test_a_new_environment_after_close_gives_the_same_episodes(expected: dict[str, np.ndarray], robot: str) -> None:
    env = make_env(robot, "train")
    env.reset(seed=0)
    env.step(steering()[0])
    env.close()
    env.close()
    again = make_env(robot, "train")
    actual = record(again)
    again.close()
    assert_same(actual["observation"], expected[f"{robot}/train/observation"])
    assert_same(actual["pose"], expected[f"{robot}/train/pose"])


if __name__ == "__main__":
    regenerate()
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size / 1024:.0f} KiB)")
