"""Top-down rgb_array rendering of the lidar course."""

from __future__ import annotations

import numpy as np
import pytest

from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv

PATH_BLUE = np.array([31, 119, 180])
ROBOT_ORANGE = np.array([255, 127, 14])
CRASH_RED = np.array([214, 39, 40])
WALL_GREY = np.array([60, 60, 60])


def count(frame, colour):
    return int(np.count_nonzero(np.all(frame == colour, axis=-1)))


def test_rgb_array_shows_walls_robot_rays_and_path():
    env = LidarObstacleCourseEnv(course="training", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.dtype == np.uint8
    assert frame.ndim == 3
    assert frame.shape[2] == 3
    assert max(frame.shape[:2]) == 480
    assert count(frame, WALL_GREY) > 1_000
    assert count(frame, ROBOT_ORANGE) > 20
    assert count(frame, PATH_BLUE) == 0  # no path yet
    for _ in range(30):
        env.step(np.zeros(1, dtype=np.float32))
    later = env.render()
    assert count(later, PATH_BLUE) > 50
    assert not np.array_equal(frame, later)
    env.close()


def test_the_robot_is_drawn_where_it_is():
    env = LidarObstacleCourseEnv(course="training", render_mode="rgb_array")
    env.reset()
    renderer_frame = env.render()
    column, row = env._renderer.to_pixels(*env.pose[:2])
    assert np.array_equal(renderer_frame[round(row) + 2, round(column) - 2], ROBOT_ORANGE)
    env.close()


def test_a_crashed_robot_is_drawn_red():
    env = LidarObstacleCourseEnv(course="training", render_mode="rgb_array")
    env.reset()
    terminated = False
    while not terminated:
        _, _, terminated, _, _ = env.step(np.ones(1, dtype=np.float32))
    frame = env.render()
    assert count(frame, CRASH_RED) > 20
    assert count(frame, ROBOT_ORANGE) == 0
    env.close()


def test_render_without_a_render_mode_warns_and_returns_none():
    env = LidarObstacleCourseEnv(course="training")
    env.reset()
    with pytest.warns(UserWarning, match="render mode"):
        assert env.render() is None
    env.close()
