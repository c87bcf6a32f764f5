"""The test-set scoring of :mod:`sb3_adc.experiment.test_sets` on the procedural lidar course (what
``benchmarks/experiments/lidar_course_v1.yml`` scores): an episode succeeds when it drives 500 steps without a
collision, a layout seed reaches the same layout and episode every time, and a failed episode records what it hit."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc.experiment.test_sets import play_episode
from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS
from sb3_adc_envs.lidar_course.planner import LidarLocalPlanner

ENV_ID = "sb3_adc/LidarObstacleCourse-v1"


class Straight:
    """A policy that never steers."""

    def __init__(self, env: gym.Env) -> None:
        self.action = np.zeros(env.action_space.shape, dtype=np.float32)

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, None]:
        return self.action, None


def layout_episode(policy: Any, env: gym.Env, layout_seed: int) -> dict[str, Any]:
    return play_episode(policy, env, seed=layout_seed, options={"layout_seed": layout_seed})


def test_success_is_500_steps_without_a_collision():
    env = gym.make(ENV_ID, layout_seeds=TEST_LAYOUT_SEEDS)
    planner = LidarLocalPlanner.for_env(env)
    outcomes = [layout_episode(planner, env, TEST_LAYOUT_SEEDS[0] + k) for k in range(4)]
    assert any(outcome["success"] for outcome in outcomes)
    for outcome in outcomes:
        if outcome["success"]:
            assert (outcome["length"], outcome["hit"], outcome["hit_unseen"]) == (500, "", False)
        else:
            assert outcome["length"] < 500
            assert outcome["hit"]
    crash = layout_episode(Straight(env), env, TEST_LAYOUT_SEEDS[0])
    assert not crash["success"]
    assert crash["length"] < 500
    assert set(crash["hit"].split(";")) <= {"wall", "box", "cylinder", "stub"}
    env.close()


def test_a_layout_seed_reaches_the_same_layout_and_episode():
    first, second = (gym.make(ENV_ID, layout_seeds=TEST_LAYOUT_SEEDS) for _ in range(2))
    seed = TEST_LAYOUT_SEEDS[0] + 3
    planner = LidarLocalPlanner.for_env(first)
    outcome = layout_episode(planner, first, seed)
    layout_episode(planner, second, TEST_LAYOUT_SEEDS[0])  # another layout in between changes nothing
    assert layout_episode(planner, second, seed) == outcome
    assert first.unwrapped.course == second.unwrapped.course  # type: ignore[attr-defined]
    first.close()
    second.close()
