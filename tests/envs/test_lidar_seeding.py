"""Seeding and start-pose jitter of the lidar course."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv, load_course


def rollout(env, seed, actions):
    observations = [env.reset(seed=seed)[0]]
    for action in actions:
        obs, _, terminated, truncated, _ = env.step(action)
        observations.append(obs)
        if terminated or truncated:
            observations.append(env.reset()[0])
    return np.array(observations)


@pytest.fixture
def actions():
    return np.random.default_rng(0).uniform(-1.0, 1.0, size=(300, 1)).astype(np.float32)


def test_same_seed_same_actions_same_observations(actions):
    kwargs = {"course": "training", "start_position_jitter": 0.2, "start_heading_jitter_deg": 10.0}
    first, second = LidarObstacleCourseEnv(**kwargs), LidarObstacleCourseEnv(**kwargs)
    np.testing.assert_array_equal(rollout(first, 7, actions), rollout(second, 7, actions))
    # The same instance replays too, after other episodes.
    np.testing.assert_array_equal(rollout(first, 7, actions), rollout(second, 7, actions))
    assert not np.array_equal(rollout(first, 7, actions), rollout(second, 8, actions))
    first.close()
    second.close()


def test_without_jitter_every_episode_starts_at_the_course_start():
    env = LidarObstacleCourseEnv(course="training")
    start = load_course("training").start
    first, _ = env.reset(seed=1)
    for seed in (2, 3, None):
        obs, _ = env.reset(seed=seed)
        np.testing.assert_array_equal(obs, first)
        assert env.pose == (start.x, start.y, start.heading)
    env.close()


def test_jitter_stays_within_its_bounds_and_varies():
    env = LidarObstacleCourseEnv(course="training", start_position_jitter=0.2, start_heading_jitter_deg=10.0)
    start = load_course("training").start
    env.reset(seed=0)
    poses = []
    for _ in range(200):
        env.reset()
        poses.append(env.pose)
    poses = np.array(poses)
    assert np.all(np.abs(poses[:, 0] - start.x) <= 0.2)
    assert np.all(np.abs(poses[:, 1] - start.y) <= 0.2)
    assert np.all(np.abs(poses[:, 2] - start.heading) <= math.radians(10.0) + 1e-12)
    assert np.std(poses[:, 0]) > 0.05
    assert np.std(poses[:, 2]) > math.radians(2.0)
    env.close()


def test_jitter_that_could_reach_a_wall_is_rejected():
    # The training start is 0.7 m from the walls; 0.5 m of jitter along both axes can reach 0.71 m away.
    with pytest.raises(ValueError, match="`start_position_jitter`"):
        LidarObstacleCourseEnv(course="training", start_position_jitter=0.5)


def test_reset_options_choose_the_start_pose():
    env = LidarObstacleCourseEnv(course="training", start_position_jitter=0.2)
    env.reset(seed=0, options={"start_pose": (6.0, 0.1, 30.0)})
    assert env.pose == pytest.approx((6.0, 0.1, math.radians(30.0)))
    with pytest.raises(ValueError, match=r"start_pose.*on a wall"):
        env.reset(options={"start_pose": (6.0, 0.7, 0.0)})
    env.close()
