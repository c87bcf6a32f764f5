"""sb3_adc/LidarObstacleCourseNoisy-v0: the lidar course with uniform observation noise."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc_envs.wrappers import UniformObservationNoise


def test_noisy_variant_adds_bounded_noise_and_keeps_the_dynamics():
    noisy = gym.make("sb3_adc/LidarObstacleCourseNoisy-v0")
    clean = gym.make("sb3_adc/LidarObstacleCourse-v0")
    assert noisy.spec.max_episode_steps == 500
    assert isinstance(noisy.unwrapped, type(clean.unwrapped))
    np.testing.assert_allclose(noisy.observation_space.low, -0.1, rtol=1e-6)
    np.testing.assert_allclose(noisy.observation_space.high, 1.1, rtol=1e-6)
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, size=(200, 1)).astype(np.float32)
    differences = []
    noisy_obs, _ = noisy.reset(seed=3)
    clean_obs, _ = clean.reset(seed=3)
    differences.append(noisy_obs - clean_obs)
    for action in actions:
        noisy_obs, noisy_reward, noisy_terminated, _, _ = noisy.step(action)
        clean_obs, clean_reward, clean_terminated, _, _ = clean.step(action)
        assert (noisy_reward, noisy_terminated) == (clean_reward, clean_terminated)
        assert noisy.observation_space.contains(noisy_obs)
        differences.append(noisy_obs - clean_obs)
        if clean_terminated:
            differences.append(noisy.reset()[0] - clean.reset()[0])
    differences = np.array(differences)
    assert np.all(np.abs(differences) <= 0.1 + 1e-6)
    assert differences.std() == pytest.approx(0.2 / np.sqrt(12.0), rel=0.1)  # uniform on [-0.1, 0.1]
    noisy.close()
    clean.close()


def test_noise_bounds_and_env_kwargs_are_make_kwargs():
    env = gym.make("sb3_adc/LidarObstacleCourseNoisy-v0", noise_low=-0.2, noise_high=0.3, course="unseen_narrow", n_rays=4)
    wrapper = env.unwrapped
    assert env.observation_space.shape == (4,)
    np.testing.assert_allclose(env.observation_space.low, -0.2, rtol=1e-6)
    assert wrapper.course.name == "unseen_narrow"
    noise = next(layer for layer in _layers(env) if isinstance(layer, UniformObservationNoise))
    assert float(noise.noise_high[0]) == pytest.approx(0.3)
    env.close()


def test_noise_is_seeded():
    first = gym.make("sb3_adc/LidarObstacleCourseNoisy-v0")
    second = gym.make("sb3_adc/LidarObstacleCourseNoisy-v0")
    np.testing.assert_array_equal(first.reset(seed=5)[0], second.reset(seed=5)[0])
    assert not np.array_equal(first.reset(seed=5)[0], second.reset(seed=6)[0])
    first.close()
    second.close()


def _layers(env):
    while True:
        yield env
        if not hasattr(env, "env"):
            return
        env = env.env
