"""Potential-based clearance shaping: the potential, the telescoping identity, what it leaves alone, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sb3_adc_envs  # noqa: F401 (registers the environments)
from sb3_adc_envs import ClearanceShaping
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv

STRAIGHT = np.zeros(1, dtype=np.float32)
LEFT = np.ones(1, dtype=np.float32)


def test_clearance_is_the_shortest_reading_less_the_radius(box_course):
    # 10 m box, robot in the middle: every wall face is 4.95 m away, beyond the 3 m range.
    env = LidarObstacleCourseEnv(course=box_course())
    _, info = env.reset()
    assert info["clearance"] == pytest.approx(3.0 - 0.15)
    # 0.5 m from the east wall's face, heading at it.
    env = LidarObstacleCourseEnv(course=box_course(10.0, (9.45, 5.0, 0.0)), n_rays=24)
    _, info = env.reset()
    assert info["clearance"] == pytest.approx(0.5 - 0.15, abs=1e-6)


@pytest.mark.parametrize(("clearance", "expected"), [(2.0, 0.0), (0.5, 0.0), (0.25, -0.25), (0.0, -0.5), (-0.1, -0.6)])
def test_potential_is_zero_with_room_and_minus_scale_touching(clearance, expected):
    shaping = ClearanceShaping(gym.make("sb3_adc/LidarObstacleCourse-v1"), gamma=0.9, safe_distance=0.5, scale=0.5)
    assert shaping.potential({"clearance": clearance}) == pytest.approx(expected)


@pytest.mark.parametrize(("max_steps", "action"), [(40, LEFT), (500, STRAIGHT)])
def test_discounted_shaping_of_an_episode_telescopes(max_steps, action):
    """sum_t gamma^t F_t = gamma^T phi(s_T) - phi(s_0), phi(s_T) = 0 when the episode terminated."""
    gamma = 0.9
    env = ClearanceShaping(gym.make("sb3_adc/LidarObstacleCourse-v1", max_episode_steps=max_steps), gamma=gamma)
    _, info = env.reset(seed=3)
    first = env.potential(info)
    total, discount, steps, terminated, truncated = 0.0, 1.0, 0, False, False
    nonzero = 0
    while not (terminated or truncated):
        _, reward, terminated, truncated, info = env.step(action)
        total += discount * info["shaping"]
        nonzero += info["shaping"] != 0.0
        # The shaped reward is the environment's plus the term; success is the environment's.
        base = -1.0 if info["collision"] else 0.001
        assert reward == pytest.approx(base + info["shaping"])
        assert info["is_success"] == (not info["collision"])
        discount *= gamma
        steps += 1
    last = 0.0 if terminated else env.potential(info)
    assert total == pytest.approx(discount * last - first, abs=1e-9)
    assert nonzero > 0  # the episode came near a wall: the identity was not a sum of zeros


def test_observations_and_termination_are_the_environments():
    plain = gym.make("sb3_adc/LidarObstacleCourse-v1")
    shaped = ClearanceShaping(gym.make("sb3_adc/LidarObstacleCourse-v1"), gamma=0.98)
    observation, _ = plain.reset(seed=7)
    shaped_observation, _ = shaped.reset(seed=7)
    np.testing.assert_array_equal(observation, shaped_observation)
    for _ in range(300):
        observation, _, terminated, truncated, _ = plain.step(LEFT)
        shaped_observation, _, shaped_terminated, shaped_truncated, _ = shaped.step(LEFT)
        np.testing.assert_array_equal(observation, shaped_observation)
        assert (terminated, truncated) == (shaped_terminated, shaped_truncated)
        if terminated or truncated:
            break


def test_noisy_variant_is_shaped_by_the_true_clearance():
    env = ClearanceShaping(gym.make("sb3_adc/LidarObstacleCourseNoisy-v1"), gamma=0.9)
    clean = gym.make("sb3_adc/LidarObstacleCourse-v1")
    _, info = env.reset(seed=1)
    _, clean_info = clean.reset(seed=1)
    assert info["clearance"] == clean_info["clearance"]


def test_an_entry_can_shape_its_environment():
    from sb3_adc.config.loader import resolve_entry

    config = resolve_entry(
        "adc",
        "sb3_adc/LidarObstacleCourse-v1",
        {
            "n_timesteps": 10,
            "policy": "MlpPolicy",
            "gamma": 0.9,
            "env_wrapper": [{"sb3_adc_envs.wrappers.ClearanceShaping": {"gamma": 0.9, "safe_distance": 0.4}}],
        },
        "test.yml",
    )
    env = config.wrap_env(gym.make("sb3_adc/LidarObstacleCourse-v1"))
    assert isinstance(env, ClearanceShaping)
    assert env.safe_distance == 0.4


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gamma": 0.0}, "`gamma`"),
        ({"gamma": 1.5}, "`gamma`"),
        ({"gamma": 0.9, "safe_distance": 0.0}, "`safe_distance`"),
        ({"gamma": 0.9, "scale": float("inf")}, "`scale`"),
    ],
)
def test_bad_parameters_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ClearanceShaping(gym.make("sb3_adc/LidarObstacleCourse-v1"), **kwargs)


def test_an_environment_without_clearance_is_refused():
    env = ClearanceShaping(gym.make("Pendulum-v1"), gamma=0.9)
    with pytest.raises(KeyError, match="clearance"):
        env.reset(seed=0)
