"""Collisions, termination, truncation at 500 steps and the rewards of the lidar course."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv

WALL_FACE = 9.95  # inner face of the far wall of the 10 m `box_course`
STRAIGHT = np.zeros(1, dtype=np.float32)


def drive(env, action, max_steps):
    """Step with a constant action until the episode ends; returns the rewards, the last flags and infos."""
    rewards, infos = [], []
    terminated = truncated = False
    for _ in range(max_steps):
        _, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        infos.append(info)
        if terminated or truncated:
            break
    return rewards, terminated, truncated, infos


def test_driving_into_a_wall_terminates_on_contact_with_the_paper_rewards(box_course):
    # Heading straight at the wall x = 9.95 from x = 8.03 at 0.1 m per step: after 17 steps the robot's rim
    # (radius 0.15) is 0.07 m short of the wall, after 18 steps it is 0.03 m into it.
    env = LidarObstacleCourseEnv(course=box_course(10.0, (8.03, 5.0, 0.0)))
    env.reset()
    rewards, terminated, truncated, infos = drive(env, STRAIGHT, 100)
    assert len(rewards) == 18
    assert terminated
    assert not truncated
    assert rewards[:-1] == [0.001] * 17
    assert rewards[-1] == -1.0
    assert infos[-1]["collision"]
    assert not any(info["collision"] for info in infos[:-1])
    assert env.pose[0] == pytest.approx(8.03 + 1.8)
    env.close()


def test_collisions_come_from_contacts_not_from_the_lidar(box_course):
    # Rays 1 cm long never reach a wall (the lidar always reads 1), yet the contact ends the episode.
    env = LidarObstacleCourseEnv(course=box_course(10.0, (8.03, 5.0, 0.0)), max_range=0.01)
    env.reset()
    rewards, terminated, _, _ = drive(env, STRAIGHT, 100)
    assert terminated
    assert len(rewards) == 18
    env.close()


def test_grazing_a_wall_side_on_is_a_collision(box_course):
    # Driving along the wall y = 0.05 with the rim 5 cm from it, then turning into it: a collision although
    # the robot never faces the wall.
    env = LidarObstacleCourseEnv(course=box_course(10.0, (2.0, 0.05 + 0.15 + 0.05, 0.0)))
    env.reset()
    _, terminated, _, infos = drive(env, np.array([-1.0], dtype=np.float32), 20)
    assert terminated
    assert infos[-1]["collision"]
    assert env.pose[1] - 0.15 < 0.05  # the rim crossed the wall's face
    env.close()


def test_episodes_are_truncated_at_500_steps(box_course):
    # Full left steering drives a circle of radius ~0.96 m in the middle of a 10 m box: never a collision.
    env = gym.make("sb3_adc/LidarObstacleCourse-v0", course=box_course(10.0, (5.0, 5.0, 0.0)))
    assert env.spec.max_episode_steps == 500
    env.reset(seed=0)
    rewards, terminated, truncated, _ = drive(env, np.ones(1, dtype=np.float32), 1_000)
    assert len(rewards) == 500
    assert truncated
    assert not terminated
    assert sum(rewards) == pytest.approx(0.5)
    env.close()


def test_the_class_alone_never_truncates(box_course):
    env = LidarObstacleCourseEnv(course=box_course(10.0, (5.0, 5.0, 0.0)))
    env.reset()
    rewards, terminated, truncated, _ = drive(env, np.ones(1, dtype=np.float32), 700)
    assert len(rewards) == 700
    assert not terminated
    assert not truncated
    assert len(env.trajectory) == 701
    env.close()


def test_steering_changes_the_heading_by_up_to_max_steer(box_course):
    env = LidarObstacleCourseEnv(course=box_course(10.0, (5.0, 5.0, 0.0)), max_steer_deg=6.0)
    env.reset()
    env.step(np.array([1.0], dtype=np.float32))
    assert env.pose[2] == pytest.approx(math.radians(6.0))
    env.step(np.array([-0.5], dtype=np.float32))
    assert env.pose[2] == pytest.approx(math.radians(3.0))
    env.step(np.array([-7.0], dtype=np.float32))  # out of range: clipped to -1
    assert env.pose[2] == pytest.approx(math.radians(-3.0))
    x, y, heading = env.pose
    env.step(STRAIGHT)
    assert env.pose[:2] == pytest.approx((x + 0.1 * math.cos(heading), y + 0.1 * math.sin(heading)))
    with pytest.raises(ValueError, match="`action`"):
        env.step(np.array([np.nan], dtype=np.float32))
    env.close()


def test_custom_rewards(box_course):
    env = LidarObstacleCourseEnv(course=box_course(10.0, (9.0, 5.0, 0.0)), step_reward=0.5, collision_reward=-10.0)
    env.reset()
    rewards, terminated, _, _ = drive(env, STRAIGHT, 100)
    assert terminated
    assert rewards[:-1] == [0.5] * (len(rewards) - 1)
    assert rewards[-1] == -10.0
    env.close()


def test_reset_restarts_at_the_start_pose_after_a_collision(box_course):
    env = LidarObstacleCourseEnv(course=box_course(10.0, (9.0, 5.0, 0.0)))
    first, _ = env.reset()
    drive(env, STRAIGHT, 100)
    again, info = env.reset()
    np.testing.assert_array_equal(first, again)
    assert env.pose == (9.0, 5.0, 0.0)
    assert not info["collision"]
    assert len(env.trajectory) == 1
    env.close()


@pytest.mark.parametrize("course", ["training", "unseen_slalom", "procedural"])
def test_the_robot_never_leaves_the_course(course):
    # Random steering meets a wall within a few dozen steps; a broad phase that misses walls lets the robot
    # drive through them and away, which the clearance of every position would show.
    env = LidarObstacleCourseEnv(course=course)
    env.action_space.seed(0)
    env.reset(seed=0)
    collisions = 0
    for _ in range(800):
        _, _, terminated, _, _ = env.step(env.action_space.sample())
        x, y, _ = env.pose
        assert env.course.clearance(x, y) > -env.course.wall_thickness, env.pose
        assert env.course.corridor is None or env.course.clearance(x, y) < env.course.corridor.width
        if terminated:
            collisions += 1
            env.reset()
    assert collisions > 5
    env.close()
