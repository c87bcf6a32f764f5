"""The lidar course's info: is_success for SB3's success rate, and the distance driven along the course."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.evaluation import evaluate_policy

import sb3_adc_envs  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv

STRAIGHT = np.zeros(1, dtype=np.float32)


def test_a_run_until_the_time_limit_is_a_success_and_a_collision_is_not(box_course):
    env = gym.make("sb3_adc/LidarObstacleCourse-v0", max_episode_steps=20)
    _, info = env.reset()
    clearance = info.pop("clearance")
    assert info == {"collision": False, "is_success": True, "distance": 0.0, "course": "training"}
    assert 0.0 < clearance < 3.0
    for _ in range(20):
        _, _, terminated, truncated, info = env.step(STRAIGHT)
    assert truncated
    assert not terminated
    assert info["is_success"]
    env.close()
    crash = LidarObstacleCourseEnv(course=box_course(10.0, (9.0, 5.0, 0.0)))
    crash.reset()
    _, _, terminated, _, info = crash.step(STRAIGHT)
    while not terminated:
        _, _, terminated, _, info = crash.step(STRAIGHT)
    assert info["collision"]
    assert not info["is_success"]
    crash.close()


def test_distance_follows_the_centre_line_forwards_and_backwards():
    # The training course's start (6, 0) lies on its bottom straight, driven towards +x.
    forward = LidarObstacleCourseEnv(course="training")
    forward.reset()
    for _ in range(10):
        _, _, _, _, info = forward.step(STRAIGHT)
    assert info["distance"] == pytest.approx(1.0)
    backward = LidarObstacleCourseEnv(course="training")
    backward.reset(options={"start_pose": (6.0, 0.0, 180.0)})
    for _ in range(10):
        _, _, _, _, info = backward.step(STRAIGHT)
    assert info["distance"] == pytest.approx(-1.0)
    # Across the line, only the part along it counts: 10 steps at 60 degrees make 0.5 m.
    slanted = LidarObstacleCourseEnv(course="training")
    slanted.reset(options={"start_pose": (6.0, -0.5, 60.0)})
    for _ in range(10):
        _, _, _, _, info = slanted.step(STRAIGHT)
    assert info["distance"] == pytest.approx(0.5, abs=1e-6)
    for env in (forward, backward, slanted):
        env.close()


def test_distance_accumulates_round_the_loop_past_its_first_vertex():
    # The loop's centre line starts at (0, 1.5), where the arc of its first corner begins; the robot drives down
    # the left straight (the loop's last edge) across that point, from arc length L - 1 to about + 0.4.
    env = LidarObstacleCourseEnv(course="training")
    env.reset(options={"start_pose": (0.0, 2.5, -90.0)})
    for _ in range(14):
        _, _, terminated, _, info = env.step(STRAIGHT)
        assert not terminated
    assert info["distance"] == pytest.approx(1.4, abs=0.05)
    env.close()


def test_distance_is_the_path_length_on_a_course_of_walls_only(box_course):
    env = LidarObstacleCourseEnv(course=box_course(10.0, (5.0, 5.0, 0.0)))
    env.reset()
    for _ in range(12):
        _, _, _, _, info = env.step(np.ones(1, dtype=np.float32))
    assert info["distance"] == pytest.approx(1.2)
    env.close()


def test_sb3_evaluate_policy_reports_the_success_rate():
    env = gym.make("sb3_adc/LidarObstacleCourse-v0", max_episode_steps=15)
    successes = []

    def callback(locals_, _globals):
        if locals_["done"]:
            successes.append(locals_["info"].get("is_success"))

    class Straight:
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return np.zeros((len(observation), 1), dtype=np.float32), None

    evaluate_policy(Straight(), env, n_eval_episodes=2, callback=callback)
    assert successes == [True, True]
    env.close()
