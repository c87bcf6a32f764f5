"""Gymnasium conventions: registration without torch, human rendering of every variant, specs and frame rates."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import HumanRendering

import sb3_adc_envs  # noqa: F401 (registers the environments)
from sb3_adc_envs.highway_obstacle import HighwayObstacleEnv


def test_gym_make_with_the_module_prefix_works_in_a_fresh_process_without_torch_or_sb3():
    code = (
        "import sys, gymnasium as gym\n"
        "for env_id in ('sb3_adc/LidarObstacleCourse-v0', 'sb3_adc/LidarObstacleCourseNoisy-v1'):\n"
        "    env = gym.make('sb3_adc_envs:' + env_id)\n"
        "    env.reset(seed=0)\n"
        "    env.step(env.action_space.sample())\n"
        "    env.close()\n"
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'stable_baselines3'))\n"
        "assert not heavy, heavy\n"
        # Only sb3_adc's light modules: the package (whose algorithms load lazily) and its extras messages.
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] == 'sb3_adc')\n"
        "assert set(loaded) <= {'sb3_adc', 'sb3_adc.extras'}, loaded\n"
        "print('ok')\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("ok")


@pytest.mark.filterwarnings("ignore:.*HumanRendering wrapper is being applied")
@pytest.mark.parametrize(
    "env_id",
    [
        "sb3_adc/LidarObstacleCourse-v0",
        "sb3_adc/LidarObstacleCourseNoisy-v0",
        "sb3_adc/LidarObstacleCourse-v1",
        "sb3_adc/LidarObstacleCourseNoisy-v1",
    ],
)
def test_every_lidar_variant_accepts_render_mode_human(env_id, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = gym.make(env_id, render_mode="human")
    assert isinstance(env, HumanRendering)  # gym.make read the entry point's render modes
    assert env.unwrapped.render_mode == "rgb_array"
    env.reset(seed=0)
    env.step(np.zeros(1, dtype=np.float32))  # draws a frame in a (dummy) window
    env.close()


def test_the_noisy_entry_point_exposes_the_clean_environments_metadata():
    clean, noisy = gym.spec("sb3_adc/LidarObstacleCourse-v0"), gym.spec("sb3_adc/LidarObstacleCourseNoisy-v0")
    from gymnasium.envs.registration import load_env_creator

    assert load_env_creator(noisy.entry_point).metadata == load_env_creator(clean.entry_point).metadata


def test_highway_spec_has_the_episode_length_and_one_frame_rate():
    env = gym.make("sb3_adc/HighwayObstacle-v0")
    config = env.unwrapped.config
    assert env.spec.max_episode_steps == config["duration"] * config["policy_frequency"] == 200
    assert env.metadata["render_fps"] == HighwayObstacleEnv.metadata["render_fps"] == config["policy_frequency"]
    env.reset(seed=0)
    assert env.metadata["render_fps"] == config["policy_frequency"]  # highway-env alone doubles it on reset
    env.close()
    other = gym.make("sb3_adc/HighwayObstacle-v0", config={"policy_frequency": 3})
    other.reset(seed=0)
    assert other.unwrapped.metadata["render_fps"] == 3
    assert HighwayObstacleEnv.metadata["render_fps"] == 5  # the class's dict is left alone
    other.close()


@pytest.mark.parametrize(
    ("blocked", "env_id"),
    [("pybullet", "sb3_adc/LidarObstacleCourse-v0"), ("highway_env", "sb3_adc/HighwayObstacle-v0")],
)
def test_a_missing_simulator_names_the_extra_to_install(blocked, env_id):
    code = (
        "import sys, gymnasium as gym\n"
        f"sys.modules[{blocked!r}] = None\n"
        "import sb3_adc\n"
        "try:\n"
        f"    gym.make({env_id!r})\n"
        "except ModuleNotFoundError as error:\n"
        "    print(error)\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr
    assert 'pip install "sb3-adc[envs]"' in result.stdout
