"""The two-dimensional lidar task (steering and speed): its action, reward and info, and that it is the
one-dimensional task when driven at full speed."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course.speed import SpeedSteeringLidarCourse

SPEED_ID = "sb3_adc/LidarObstacleCourseSpeed-v1"


def test_it_is_registered_with_a_two_dimensional_action():
    env = gym.make(SPEED_ID)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    assert env.observation_space.shape == (24,)
    assert gym.spec(SPEED_ID).max_episode_steps == 500
    env.close()


@pytest.mark.parametrize(("throttle", "fraction"), [(-1.0, 0.25), (0.0, 0.625), (1.0, 1.0), (-3.0, 0.25), (5.0, 1.0)])
def test_the_second_action_sets_the_distance_and_the_reward_of_a_step(throttle, fraction):
    env = gym.make(SPEED_ID)
    env.reset(seed=0)
    x0, y0, _ = env.unwrapped.pose
    _, reward, terminated, _, info = env.step(np.array([0.0, throttle], dtype=np.float32))
    x1, y1, _ = env.unwrapped.pose
    assert not terminated
    assert np.hypot(x1 - x0, y1 - y0) == pytest.approx(0.1 * fraction)
    assert info["speed"] == pytest.approx(0.1 * fraction)
    assert reward == pytest.approx(0.001 * fraction)
    assert env.unwrapped.speed == env.unwrapped.top_speed == 0.1
    env.close()


def test_at_full_speed_it_drives_the_one_dimensional_task_exactly():
    """Same observations, terminations, info and trajectory; only the reward differs (progress, not survival)."""
    flat, speed = gym.make("sb3_adc/LidarObstacleCourse-v1"), gym.make(SPEED_ID)
    steering = np.random.default_rng(0).uniform(-1, 1, 200)
    for env in (flat, speed):
        env.reset(seed=3)
    for steer in steering:
        a = flat.step(np.array([steer], dtype=np.float32))
        b = speed.step(np.array([steer, 1.0], dtype=np.float32))
        np.testing.assert_array_equal(a[0], b[0])
        assert a[2:4] == b[2:4]
        assert {**a[4], "speed": 0.1} == b[4]
        if a[2]:
            break
    np.testing.assert_array_equal(flat.unwrapped.trajectory, speed.unwrapped.trajectory)


def test_the_reward_is_the_progress_along_the_course():
    env = gym.make(SPEED_ID)
    env.reset(seed=0)
    for action in ([0.0, 1.0], [1.0, -1.0], [1.0, 1.0], [-0.5, 0.3]):
        before = env.unwrapped.simulation.pose
        distance = env.unwrapped._distance
        _, reward, terminated, _, info = env.step(np.array(action, dtype=np.float32))
        assert not terminated
        assert before != env.unwrapped.simulation.pose
        assert reward == pytest.approx(0.001 * (info["distance"] - distance) / 0.1)
    # circling on the spot earns (almost) nothing: the centre line's progress comes back to where it started
    total = 0.0
    for _ in range(60):
        total += env.step(np.array([1.0, -1.0], dtype=np.float32))[1]
    assert abs(total) < 0.003
    env.close()


def test_a_collision_costs_the_collision_reward_at_any_speed():
    env = gym.make(SPEED_ID)
    env.reset(seed=1)
    for _ in range(500):
        _, reward, terminated, _, info = env.step(np.array([0.0, -1.0], dtype=np.float32))
        if terminated:
            break
    else:
        pytest.fail("driving straight at the lowest speed never hit anything")
    assert info["collision"]
    assert not info["is_success"]
    assert reward == -1.0


def test_bad_inputs_name_the_parameter():
    with pytest.raises(ValueError, match="min_speed_fraction"):
        SpeedSteeringLidarCourse(min_speed_fraction=1.0)
    with pytest.raises(ValueError, match="min_speed_fraction"):
        SpeedSteeringLidarCourse(min_speed_fraction=True)
    env = SpeedSteeringLidarCourse()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action\[1\]"):
        env.step(np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.array([0.0]))
    assert env.speed == env.top_speed
    env.close()
