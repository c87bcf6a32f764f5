"""The wheeled robot of the lidar course (``robot="wheeled"``): a differential-drive robot simulated by pybullet."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pybullet
import pytest
from gymnasium.utils.env_checker import check_env

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv
from sb3_adc_envs.lidar_course.wheeled import MAX_WHEEL_SPEED, WHEEL_RADIUS, WheeledRobot

STRAIGHT = np.zeros(1, dtype=np.float32)
LEFT = np.ones(1, dtype=np.float32)
RIGHT = -np.ones(1, dtype=np.float32)


def wheeled(course, **kwargs):
    return LidarObstacleCourseEnv(course=course, robot="wheeled", **kwargs)


@pytest.mark.parametrize("robot", ["dynamic", "Wheeled", "", None, 1])
def test_an_unknown_robot_is_refused_naming_the_parameter(robot):
    with pytest.raises(ValueError, match=r"`robot` must be one of \('kinematic', 'wheeled'\)"):
        LidarObstacleCourseEnv(course="training", robot=robot)


def test_a_body_too_small_for_the_wheels_is_refused():
    with pytest.raises(ValueError, match="`robot_radius`"):
        LidarObstacleCourseEnv(course="training", robot="wheeled", robot_radius=0.05)


def test_registered_ids_stay_kinematic_and_make_takes_the_option():
    for env_id in ("sb3_adc/LidarObstacleCourse-v1", "sb3_adc/LidarObstacleCourseNoisy-v1"):
        env = gym.make(env_id)
        assert env.unwrapped.robot == "kinematic"
        env.close()
        env = gym.make(env_id, robot="wheeled")
        assert env.unwrapped.robot == "wheeled"
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        env.close()


@pytest.mark.parametrize("env_id", ["sb3_adc/LidarObstacleCourse-v0", "sb3_adc/LidarObstacleCourse-v1"])
def test_gymnasium_check_env(env_id):
    # The environment gym.make builds, without its wrappers (it carries its spec for the render-mode checks).
    env = gym.make(env_id, robot="wheeled", render_mode="rgb_array").unwrapped
    check_env(env)
    env.close()


def test_driving_straight_advances_speed_per_step_once_at_speed(box_course):
    # From rest the robot reaches its speed within 4 steps (0.1 s each); after that every step advances
    # `speed` within 2%, and the robot keeps its line and heading within 1 mm and 0.2 degrees.
    env = wheeled(box_course(10.0, (2.0, 5.0, 0.0)), speed=0.08)
    env.reset()
    for _ in range(4):
        env.step(STRAIGHT)
    for _ in range(10):
        x, _, _ = env.pose
        env.step(STRAIGHT)
        assert env.pose[0] - x == pytest.approx(0.08, rel=0.02)
        assert env.pose[1] == pytest.approx(5.0, abs=1e-3)
        assert env.pose[2] == pytest.approx(0.0, abs=math.radians(0.2))
    env.close()


@pytest.mark.parametrize(("action", "sign"), [(LEFT, 1.0), (RIGHT, -1.0), (0.5 * LEFT, 0.5)])
def test_steering_turns_as_the_kinematic_robot_does(box_course, action, sign):
    # Positive turns left (counter-clockwise), as in the kinematic mode; once at speed the heading changes by
    # `action * max_steer_deg` per step within 5%.
    env = wheeled(box_course(10.0, (5.0, 5.0, 0.0)), max_steer_deg=6.0)
    env.reset()
    for _ in range(4):
        env.step(action)
    for _ in range(10):
        heading = env.pose[2]
        env.step(action)
        turn = math.remainder(env.pose[2] - heading, 2.0 * math.pi)
        assert turn == pytest.approx(sign * math.radians(6.0), rel=0.05)
    env.close()


def test_driving_into_a_wall_terminates_with_the_collision_reward(box_course):
    env = wheeled(box_course(10.0, (8.03, 5.0, 0.0)))
    env.reset()
    rewards = []
    for _ in range(100):
        _, reward, terminated, truncated, info = env.step(STRAIGHT)
        rewards.append(reward)
        if terminated:
            break
    assert terminated
    assert not truncated
    assert rewards[:-1] == [0.001] * (len(rewards) - 1)
    assert rewards[-1] == -1.0
    assert info["collision"]
    assert not info["is_success"]
    assert env.pose[0] + 0.15 >= 9.95  # the body's rim reached the wall's face
    assert info["distance"] == pytest.approx(env.pose[0] - 8.03)
    env.close()


def test_same_seed_same_trajectory():
    kwargs = {"start_position_jitter": 0.2, "start_heading_jitter_deg": 10.0}
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, size=(50, 1)).astype(np.float32)

    def rollout(env, seed):
        observations, poses = [env.reset(seed=seed)[0]], [env.pose]
        for action in actions:
            observations.append(env.step(action)[0])
            poses.append(env.pose)
        return np.array(observations), np.array(poses)

    first, second = wheeled("training", **kwargs), wheeled("training", **kwargs)
    observations, poses = rollout(first, 3)
    again = rollout(second, 3)
    np.testing.assert_array_equal(observations, again[0])
    np.testing.assert_array_equal(poses, again[1])
    rollout(first, 4)  # another episode in between: a reset restores every state
    np.testing.assert_array_equal(poses, rollout(first, 3)[1])
    assert not np.array_equal(poses, rollout(second, 4)[1])
    first.close()
    second.close()


def test_the_lidar_reads_what_the_kinematic_robot_reads_at_the_same_pose():
    kinematic, dynamic = LidarObstacleCourseEnv(course="unseen_slalom"), wheeled("unseen_slalom")
    for pose in [(6.0, 0.1, 30.0), (2.0, -0.3, 200.0), (8.0, 3.0, 95.0)]:
        np.testing.assert_array_equal(
            kinematic.reset(options={"start_pose": pose})[0], dynamic.reset(options={"start_pose": pose})[0]
        )
    kinematic.close()
    dynamic.close()


def test_close_disconnects_the_client():
    env = wheeled("training")
    client = env.simulation.client_id
    assert pybullet.isConnected(client)
    env.close()
    assert not pybullet.isConnected(client)
    env.close()
    assert env.simulation.client_id is None


def test_wheel_speeds_keep_their_ratio_within_the_limit():
    robot = WheeledRobot(radius=0.15, body_height=0.2, base_height=0.15)
    assert robot.track_width == pytest.approx(0.24)
    left, right = robot.wheel_speeds(0.1, math.radians(6.0))
    assert right > left > 0.0
    assert (left + right) / 2.0 * WHEEL_RADIUS == pytest.approx(1.0)  # 0.1 m per 0.1 s
    assert (right - left) * WHEEL_RADIUS / robot.track_width == pytest.approx(math.radians(60.0))
    fast_left, fast_right = robot.wheel_speeds(1.0, math.radians(60.0))
    assert fast_right == pytest.approx(MAX_WHEEL_SPEED)
    assert fast_left / fast_right == pytest.approx((10.0 - math.radians(600.0) * 0.12) / (10.0 + math.radians(600.0) * 0.12))
