"""The reference local planner of the lidar course: its plans, its choices on made-up scans, a drive, bad input."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course.planner import LidarLocalPlanner

N_RAYS = 24
ANGLES = np.arange(N_RAYS) * 2 * math.pi / N_RAYS
ROBOT = {"max_range": 3.0, "speed": 0.1, "max_steer": math.radians(6.0), "robot_radius": 0.15}


def planner(**kwargs):
    return LidarLocalPlanner(ANGLES, **ROBOT, **kwargs)


def scan_with(points):
    """A clean scan (distances / range) of the given (angle [deg], distance [m]) readings, the other rays free."""
    scan = np.ones(N_RAYS, dtype=np.float32)
    for angle_deg, distance in points:
        scan[round(angle_deg / 15.0) % N_RAYS] = distance / ROBOT["max_range"]
    return scan


def test_plans_follow_the_robots_motion_model():
    plans = planner(horizon=10, n_steers=3, switch_steps=(4,))
    straight = np.flatnonzero((plans.plan_steers == 0.0).all(axis=1))[0]
    np.testing.assert_allclose(plans.plan_points[straight], np.stack([0.1 * np.arange(1, 11), np.zeros(10)], -1), atol=1e-12)
    left = np.flatnonzero((plans.plan_steers == 1.0).all(axis=1))[0]
    points = plans.plan_points[left]
    steps = np.diff(np.vstack([[0.0, 0.0], points]), axis=0)
    np.testing.assert_allclose(np.linalg.norm(steps, axis=1), 0.1)  # the speed of every step
    headings = np.unwrap(np.arctan2(steps[:, 1], steps[:, 0]))
    np.testing.assert_allclose(np.diff(headings), math.radians(6.0))  # the turn limit of every step
    assert (points[:, 1] > 0).all()  # positive steering turns left, as in the environment
    # 3 first values x 3 second values x 1 switch step
    assert plans.plan_steers.shape == (9, 10)


def test_free_scan_drives_straight():
    action = planner().act(np.ones(N_RAYS, dtype=np.float32))
    assert action.shape == (1,)
    assert action.dtype == np.float32
    assert action[0] == 0.0


def test_turns_away_from_an_obstacle_ahead_and_from_a_near_wall():
    wall_left = scan_with([(a, 0.35) for a in (30, 45, 60, 75, 90)] + [(0, 1.2), (15, 1.0)])
    assert planner().act(wall_left)[0] < 0.0  # turns right, away from the obstacle on the left
    wall_right = scan_with([(-a, 0.35) for a in (30, 45, 60, 75, 90)] + [(0, 1.2), (-15, 1.0)])
    assert planner().act(wall_right)[0] > 0.0
    # The same reading gives the same action (no memory).
    assert planner().act(wall_left)[0] == planner().act(wall_left.copy())[0]


def test_predict_has_sb3s_signature():
    action, state = planner().predict(np.ones(N_RAYS, dtype=np.float32), deterministic=True)
    assert state is None
    assert action.shape == (1,)


def test_drives_a_shipped_obstacle_course_where_driving_straight_crashes():
    env = gym.make("sb3_adc/LidarObstacleCourse-v1", course="unseen_slalom")
    plans = LidarLocalPlanner.for_env(env)

    def episode(policy):
        observation, _ = env.reset(seed=0)
        for _ in range(500):
            observation, _, terminated, truncated, info = env.step(policy(observation))
            if terminated or truncated:
                return info
        raise AssertionError("the 500-step limit did not end the episode")

    assert not episode(lambda _: np.zeros(1, dtype=np.float32))["is_success"]
    info = episode(plans.act)
    assert info["is_success"]
    assert info["distance"] > 40.0


def test_noisy_variant_reads_its_noise_bounds():
    env = gym.make("sb3_adc/LidarObstacleCourseNoisy-v1")
    plans = LidarLocalPlanner.for_env(env)
    np.testing.assert_allclose(plans.noise_low, -0.1)
    np.testing.assert_allclose(plans.noise_high, 0.1)
    # A reading of 0.95 may be a free ray under noise: no point, the planner drives straight.
    assert plans.act(np.full(plans.ray_angles.size, 0.95, dtype=np.float32))[0] == 0.0
    # Clean, the same reading is a wall all round 2.85 m away, which the plans do not reach either.
    assert planner().act(np.full(N_RAYS, 0.95, dtype=np.float32))[0] == 0.0
    # A reading that is a hit under any noise is placed at its nearest possible distance.
    near = scan_with([(0, 0.75)])
    near_plans = LidarLocalPlanner(ANGLES, **ROBOT, noise_low=-0.1, noise_high=0.1)
    assert planner().act(near)[0] != 0.0
    assert near_plans.act(near)[0] != 0.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"horizon": 0}, "`horizon`"),
        ({"n_steers": 1}, "`n_steers`"),
        ({"switch_steps": (50,)}, "`switch_steps`"),
        ({"switch_steps": ()}, "`switch_steps`"),
        ({"margin": -0.1}, "`margin`"),
        ({"turn_cost": float("nan")}, "`turn_cost`"),
        ({"noise_low": 0.1, "noise_high": -0.1}, "`noise_low`"),
    ],
)
def test_bad_parameters_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        planner(**kwargs)


def test_bad_robot_and_observation_are_named():
    with pytest.raises(ValueError, match="`speed`"):
        LidarLocalPlanner(ANGLES, **{**ROBOT, "speed": 0.0})
    with pytest.raises(ValueError, match="24 rays"):
        planner().act(np.ones(8, dtype=np.float32))
    with pytest.raises(TypeError, match="lidar course environment"):
        LidarLocalPlanner.for_env(gym.make("Pendulum-v1"))
