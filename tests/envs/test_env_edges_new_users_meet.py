"""Edges a new user meets: bounded lidar keywords named in errors, and no false warnings or SDL noise."""

import os
import subprocess
import sys

import numpy as np
import pytest

from sb3_adc_envs.lidar_course.env import MAX_N_RAYS, LidarObstacleCourseEnv


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"n_rays": MAX_N_RAYS + 1}, ValueError, rf"`n_rays` must be an integer in \[1, {MAX_N_RAYS}\]"),
        ({"speed": "1e300"}, TypeError, r"`speed` must be a number, got '1e300' \(str\)"),
        ({"fov_deg": "360"}, TypeError, r"`fov_deg` must be a number"),
        ({"step_reward": float("nan")}, ValueError, r"`step_reward` must be a finite number"),
        ({"speed": 1e300}, ValueError, r"`speed` must be in \(0, 200\] m \(MAX_COURSE_SIDE.*got 1e\+300"),
        ({"max_range": 1e6}, ValueError, r"`max_range` must be in \(0, 200\] m"),
    ],
)
def test_lidar_keywords_out_of_range_are_named(kwargs, error, message):
    with pytest.raises(error, match=message):
        LidarObstacleCourseEnv(**kwargs)


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ({"lanes_count": 1_000_000}, r"config\['lanes_count'\] must be an integer in \[2, 16\]"),
        (
            {"observation": {"type": "RoadEdgeLidarObservation", "cells": 10**6}},
            r"\['cells'\] must be an integer in \[1, 4096\]",
        ),
        ({"ego_speed": "fast"}, r"config\['ego_speed'\] must be a finite number, got 'fast' \(str\)"),
        ({"duration": float("inf")}, r"config\['duration'\] must be a finite number"),
        ({"obstacle_gap": [40.0, "far"]}, r"config\['obstacle_gap'\]"),
    ],
)
def test_highway_configuration_out_of_range_is_named(config, message):
    pytest.importorskip("highway_env")
    from sb3_adc_envs.highway_obstacle import HighwayObstacleEnv

    with pytest.raises(ValueError, match=message):
        HighwayObstacleEnv(config=config)


def test_numpy_numbers_are_numbers():
    env = LidarObstacleCourseEnv(n_rays=np.int64(8), speed=np.float32(0.1), max_range=np.float64(3.0))
    assert env.observation_space.shape == (8,)
    env.close()


def run_python(code: str, **environment: str | None) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter with all warnings shown (``-W always``), ``environment`` changed."""
    env = dict(os.environ)
    for name, value in environment.items():
        if value is None:
            env.pop(name, None)
        else:
            env[name] = value
    command = [sys.executable, "-W", "always", "-c", code]
    return subprocess.run(command, capture_output=True, text=True, env=env, timeout=120, check=True)


def test_fixed_course_ids_do_not_warn_that_they_are_out_of_date():
    code = (
        "import gymnasium as gym, sb3_adc_envs\n"
        "for env_id in ('sb3_adc/LidarObstacleCourse-v0', 'sb3_adc/LidarObstacleCourseNoisy-v0'):\n"
        "    gym.make(env_id).close()\n"
        "gym.register('Other-v0', entry_point='gymnasium.envs.classic_control:PendulumEnv')\n"
        "gym.register('Other-v1', entry_point='gymnasium.envs.classic_control:PendulumEnv')\n"
        "gym.make('Other-v0').close()\n"
    )
    err = run_python(code).stderr
    assert "sb3_adc/LidarObstacleCourse" not in err
    assert "The environment Other-v0 is out of date" in err  # Gymnasium's warning stays for other ids


def test_highway_rendering_prints_no_sdl_error():
    pytest.importorskip("highway_env")
    code = (
        "import os, gymnasium as gym, sb3_adc_envs\n"
        "env = gym.make('sb3_adc/HighwayObstacle-v0', render_mode='rgb_array')\n"
        "env.reset(seed=0)\n"
        "frame = env.render()\n"
        "assert frame.shape[2] == 3 and frame.std() > 0\n"
        "assert 'XDG_RUNTIME_DIR' not in os.environ\n"
        "env.close()\n"
    )
    result = run_python(code, XDG_RUNTIME_DIR=None, SDL_VIDEODRIVER=None, DISPLAY=None, WAYLAND_DISPLAY=None)
    assert "XDG_RUNTIME_DIR" not in result.stderr + result.stdout
