"""sb3_adc/NoisyPendulum-v1 and the UniformObservationNoise wrapper (ADC paper, Section 5.2)."""

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import sb3_adc  # noqa: F401  (registers the environments)
from sb3_adc_envs import UniformObservationNoise

ENV_ID = "sb3_adc/NoisyPendulum-v1"


def rollout(env, seed, n_steps=50):
    observations = [env.reset(seed=seed)[0]]
    env.action_space.seed(seed)
    for _ in range(n_steps):
        observations.append(env.step(np.array([0.5], dtype=np.float32))[0])
    return np.array(observations)


def test_registered_with_pendulum_episode_length():
    spec = gym.spec(ENV_ID)
    assert spec.max_episode_steps == 200
    assert spec.kwargs == {"noise_low": -0.1, "noise_high": 0.1}


def test_passes_gymnasium_and_sb3_env_checkers():
    gym_check_env(gym.make(ENV_ID).unwrapped)
    gym_check_env(gym.make(ENV_ID))
    sb3_check_env(gym.make(ENV_ID))


def test_noise_is_uniform_within_bounds_on_every_channel():
    clean = rollout(gym.make("Pendulum-v1"), seed=0, n_steps=2000)
    noisy = rollout(gym.make(ENV_ID), seed=0, n_steps=2000)
    noise = noisy - clean
    assert noise.shape == (2001, 3)
    assert noise.min() >= -0.1 - 1e-6
    assert noise.max() <= 0.1 + 1e-6
    # Uniform on [-0.1, 0.1]: mean 0, standard deviation 0.2 / sqrt(12) = 0.0577 (the paper's 0.0578).
    np.testing.assert_allclose(noise.mean(axis=0), 0.0, atol=0.006)
    np.testing.assert_allclose(noise.std(axis=0), 0.2 / np.sqrt(12), atol=0.004)
    # Independent across channels.
    correlation = np.corrcoef(noise.T)
    assert np.all(np.abs(correlation[np.triu_indices(3, 1)]) < 0.08)


def test_noise_bounds_are_make_kwargs():
    clean = rollout(gym.make("Pendulum-v1"), seed=1, n_steps=500)
    noisy = rollout(gym.make(ENV_ID, noise_low=0.2, noise_high=0.3), seed=1, n_steps=500)
    noise = noisy - clean
    assert noise.min() >= 0.2 - 1e-6
    assert noise.max() <= 0.3 + 1e-6


def test_observation_space_is_widened_by_the_noise():
    space = gym.make(ENV_ID).observation_space
    np.testing.assert_allclose(space.low, [-1.1, -1.1, -8.1], rtol=1e-6)
    np.testing.assert_allclose(space.high, [1.1, 1.1, 8.1], rtol=1e-6)


def test_same_seed_same_observations_and_other_seed_other_noise():
    first = rollout(gym.make(ENV_ID), seed=5)
    second = rollout(gym.make(ENV_ID), seed=5)
    np.testing.assert_array_equal(first, second)
    assert not np.array_equal(first, rollout(gym.make(ENV_ID), seed=6))


def test_noise_leaves_the_wrapped_environment_dynamics_untouched():
    # The wrapper draws from its own generator: the pendulum's trajectory is the clean one.
    env = gym.make(ENV_ID)
    clean = gym.make("Pendulum-v1")
    env.reset(seed=3)
    clean.reset(seed=3)
    for _ in range(20):
        env.step(np.array([1.0], dtype=np.float32))
        clean.step(np.array([1.0], dtype=np.float32))
    np.testing.assert_array_equal(env.unwrapped.state, clean.unwrapped.state)


def test_wrapper_rejects_bad_arguments():
    with pytest.raises(TypeError, match="Box observation space"):
        UniformObservationNoise(gym.make("Blackjack-v1"))
    with pytest.raises(ValueError, match="`high` must be >= `low`"):
        UniformObservationNoise(gym.make("Pendulum-v1"), low=0.1, high=-0.1)
    with pytest.raises(ValueError, match="finite"):
        UniformObservationNoise(gym.make("Pendulum-v1"), low=-np.inf)


def test_per_channel_bounds():
    env = UniformObservationNoise(gym.make("Pendulum-v1"), low=np.array([0.0, -0.5, 0.0]), high=np.array([0.0, 0.5, 1.0]))
    assert isinstance(env.observation_space, spaces.Box)
    np.testing.assert_allclose(env.observation_space.high, [1.0, 1.5, 9.0])


def test_importing_sb3_adc_registers_without_importing_simulators():
    code = (
        "import sys, gymnasium as gym, sb3_adc; "
        "assert 'sb3_adc/NoisyPendulum-v1' in gym.registry; "
        "assert 'pybullet' not in sys.modules and 'highway_env' not in sys.modules, sorted(sys.modules)"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_noise_draws_are_those_of_rng_uniform_on_the_bounds():
    # The wrapper draws into a preallocated buffer; the values must be exactly numpy's uniform draws.
    from gymnasium.utils import seeding

    wrapper = UniformObservationNoise(gym.make("Pendulum-v1"), low=np.array([-0.1, -0.3, 0.0]), high=0.1)
    wrapper.reset(seed=11)
    reference, _ = seeding.np_random(11)
    reference.uniform(wrapper.noise_low, wrapper.noise_high)  # the reset observation's noise
    observation = np.array([0.5, -0.25, 3.0], dtype=np.float32)
    for _ in range(2000):
        expected = (observation + reference.uniform(wrapper.noise_low, wrapper.noise_high)).astype(np.float32)
        np.testing.assert_array_equal(wrapper.observation(observation), expected)
