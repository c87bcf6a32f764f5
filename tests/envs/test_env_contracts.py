"""Every environment of this package passes Gymnasium's and SB3's checkers and trains with ADC, DDPG and TD3."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gymnasium_check_env
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit
from stable_baselines3 import DDPG, TD3
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import sb3_adc
from sb3_adc import ADC, EpsilonGaussianNoise
from sb3_adc_envs.registration import ENV_SPECS

ENV_IDS = [
    "sb3_adc/LidarObstacleCourse-v0",
    "sb3_adc/LidarObstacleCourseNoisy-v0",
    "sb3_adc/LidarObstacleCourse-v1",
    "sb3_adc/LidarObstacleCourseNoisy-v1",
    "sb3_adc/LidarObstacleCourseSpeed-v1",
    "sb3_adc/HighwayObstacle-v0",
    "sb3_adc/HighwayObstacle-v1",
]
TINY = {
    ADC: {"net_arch": {"pi": [8], "qf": [8]}, "n_intervals": 10, "value_net_arch": [4]},
    DDPG: {"net_arch": {"pi": [8], "qf": [8]}},
    TD3: {"net_arch": {"pi": [8], "qf": [8]}},
}


def test_the_environments_are_registered():
    for env_id in ENV_IDS:
        assert env_id in ENV_SPECS
        assert env_id in gym.registry
    assert gym.spec("sb3_adc/LidarObstacleCourse-v0").max_episode_steps == 500
    assert gym.spec("sb3_adc/LidarObstacleCourseNoisy-v0").max_episode_steps == 500
    assert gym.spec("sb3_adc/LidarObstacleCourse-v1").max_episode_steps == 500
    assert gym.spec("sb3_adc/LidarObstacleCourseNoisy-v1").max_episode_steps == 500
    assert gym.spec("sb3_adc/LidarObstacleCourseSpeed-v1").max_episode_steps == 500
    assert gym.spec("sb3_adc/HighwayObstacle-v0").max_episode_steps == 200
    assert gym.spec("sb3_adc/HighwayObstacle-v1").max_episode_steps == 200


def test_importing_sb3_adc_imports_neither_pybullet_nor_highway_env():
    code = (
        "import sys, gymnasium as gym, sb3_adc; "
        "assert 'sb3_adc/LidarObstacleCourse-v0' in gym.registry; "
        "assert 'sb3_adc/HighwayObstacle-v0' in gym.registry; "
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('pybullet', 'pybullet_data', 'highway_env', 'pygame')); "
        "assert not heavy, heavy"
    )
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)


def core_env(env_id, **kwargs):
    """``gym.make`` without the wrappers it adds: what the registered entry point returns (with its spec)."""
    env = gym.make(env_id, **kwargs)
    while isinstance(env, (TimeLimit, OrderEnforcing, PassiveEnvChecker)):
        env = env.env
    return env


# The noisy variant is a wrapper (the noise) around the environment: Gymnasium's checker warns about wrappers.
@pytest.mark.filterwarnings("ignore:.*is different from the unwrapped version")
@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_check_env(env_id, render_mode):
    env = core_env(env_id, render_mode=render_mode)
    gymnasium_check_env(env, skip_render_check=render_mode is None)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_check_env(env_id):
    env = gym.make(env_id)
    sb3_check_env(env, warn=True)
    env.close()


@pytest.mark.parametrize("algorithm", [ADC, DDPG, TD3], ids=lambda algorithm: algorithm.__name__)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_algorithms_run_a_few_hundred_steps(env_id, algorithm):
    env = gym.make(env_id)
    n_actions = env.action_space.shape[0]
    noise = EpsilonGaussianNoise(np.zeros(n_actions), 0.3 * np.ones(n_actions), decay_steps=200)
    model = algorithm(
        "MlpPolicy",
        env,
        learning_starts=100,
        batch_size=16,
        buffer_size=1_000,
        action_noise=noise,
        policy_kwargs=TINY[algorithm],
        seed=0,
        device="cpu",
    )
    model.learn(300)
    assert model.num_timesteps == 300
    assert model.replay_buffer.size() == 300
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)
    env.close()


def test_sb3_adc_version_is_importable():
    assert isinstance(sb3_adc.__version__, str)
