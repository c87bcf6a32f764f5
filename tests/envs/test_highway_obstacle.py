"""sb3_adc/HighwayObstacle-v0 and -v1: steering-only obstacle avoidance on highway-env."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc_envs.highway_obstacle import PAPER_STEERING_RANGE, HighwayObstacleEnv

STRAIGHT = np.zeros(1, dtype=np.float32)
NO_OBSTACLES = {"first_obstacle_distance": 1e6}


def make(config=None, render_mode=None):
    return gym.make("sb3_adc/HighwayObstacle-v0", config=config, render_mode=render_mode)


def run(env, action, max_steps=1_000):
    rewards = []
    for _ in range(max_steps):
        _, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        if terminated or truncated:
            return rewards, terminated, truncated, info
    raise AssertionError("the episode did not end")


def test_spaces_steering_range_and_constant_speed():
    env = make(NO_OBSTACLES)
    env.reset(seed=0)
    unwrapped = env.unwrapped
    assert env.action_space.shape == (1,)
    assert env.action_space.low[0] == -1.0
    assert env.action_space.high[0] == 1.0
    assert env.observation_space.shape == (16,)
    assert env.observation_space.low.min() == 0.0
    assert env.observation_space.high.max() == 1.0
    assert tuple(unwrapped.action_type.steering_range) == pytest.approx(PAPER_STEERING_RANGE)
    assert PAPER_STEERING_RANGE[1] == pytest.approx(math.radians(6.0))
    assert not unwrapped.action_type.longitudinal
    assert unwrapped.action_type.lateral
    for action in (0.3, -0.3, 0.0):
        env.step(np.array([action], dtype=np.float32))
        assert unwrapped.vehicle.speed == pytest.approx(20.0)
        assert unwrapped.vehicle.action["steering"] == pytest.approx(action * math.radians(6.0))
    env.close()


def test_hitting_an_obstacle_terminates_with_minus_one():
    # Lane 1 only, an obstacle row every 50 m blocking it: driving straight must hit the first one.
    env = make({"lanes_count": 2, "max_blocked_lanes": 1, "obstacle_gap": [50.0, 50.0]})
    env.reset(seed=0)
    unwrapped = env.unwrapped
    lane_y = unwrapped.vehicle.position[1]
    unwrapped.road.objects = [obstacle for obstacle in unwrapped.road.objects if obstacle.position[1] == lane_y]
    rewards, terminated, truncated, info = run(env, STRAIGHT)
    assert terminated
    assert not truncated
    assert info["collision"]
    assert not info["is_success"]
    assert unwrapped.vehicle.crashed
    assert rewards[-1] == -1.0
    assert set(rewards[:-1]) == {0.001}
    env.close()


def test_leaving_the_road_terminates_with_minus_one():
    env = make(NO_OBSTACLES)
    env.reset(seed=0)
    rewards, terminated, _, info = run(env, np.ones(1, dtype=np.float32))
    assert terminated
    assert info["off_road"]
    assert not info["collision"]
    assert not info["is_success"]
    assert rewards[-1] == -1.0
    y_right, y_left = env.unwrapped.road_edges
    y = env.unwrapped.vehicle.position[1]
    assert y > y_left - 1.5 or y < y_right + 1.5  # within a half car-width and a bit of an edge
    env.close()


def test_episodes_are_truncated_after_duration():
    env = make({**NO_OBSTACLES, "duration": 4.0, "policy_frequency": 5})
    env.reset(seed=0)
    rewards, terminated, truncated, info = run(env, STRAIGHT)
    assert truncated
    assert not terminated
    assert info["is_success"]
    assert len(rewards) == 20
    assert sum(rewards) == pytest.approx(0.02)
    env.close()


def test_the_lidar_sees_the_road_edges_and_turns_with_the_car():
    env = make(NO_OBSTACLES)
    obs, _ = env.reset(seed=0)
    unwrapped = env.unwrapped
    y = unwrapped.vehicle.position[1]
    y_right, y_left = unwrapped.road_edges
    # Rays are 22.5 deg apart from the heading: ray 4 points at +y, ray 12 at -y, rays 0 and 8 along the road.
    assert obs[4] == pytest.approx((y_left - y) / 50.0, abs=1e-5)
    assert obs[12] == pytest.approx((y - y_right) / 50.0, abs=1e-5)
    assert obs[0] == 1.0
    assert obs[8] == 1.0
    expected = unwrapped.observation_type.edge_distances(unwrapped.vehicle.position, 0.0)
    np.testing.assert_allclose(obs, np.minimum(expected / 50.0, 1.0), atol=1e-5)
    # Turned by 0.2 rad, the ray along the heading meets an edge 50 m ahead or nearer.
    obs, *_ = env.step(np.ones(1, dtype=np.float32) * (1.0 if y < (y_left + y_right) / 2 else -1.0))
    heading = unwrapped.vehicle.heading
    assert heading != 0.0
    np.testing.assert_allclose(
        obs, np.minimum(unwrapped.observation_type.edge_distances(unwrapped.vehicle.position, heading) / 50.0, 1.0), atol=1e-5
    )
    env.close()


def test_the_lidar_sees_obstacles_ahead():
    from highway_env.vehicle.objects import Obstacle

    env = make(NO_OBSTACLES)
    env.reset(seed=1)
    unwrapped = env.unwrapped
    x, y = unwrapped.vehicle.position
    assert unwrapped.observation_type.observe()[0] == 1.0
    unwrapped.road.objects = [Obstacle(unwrapped.road, [x + 30.0, y])]
    obs = unwrapped.observation_type.observe()
    assert obs[0] == pytest.approx((30.0 - 1.0) / 50.0, abs=1e-3)  # the obstacle's near face, 1 m before its centre
    assert obs[8] == 1.0
    env.close()


def closest_own_lane_readings(env_id: str, distance: float) -> float:
    """
    How far the readings of an obstacle in the next lane, ``distance`` ahead, are from those of the most alike
    obstacle in the car's own lane (at any distance within 3 m of it, 2 cm apart, or out of the lidar's range):
    the largest difference of a ray.
    """
    from highway_env.vehicle.objects import Obstacle

    env = gym.make(env_id, config=NO_OBSTACLES)
    env.reset(seed=0)
    unwrapped = env.unwrapped
    unwrapped.vehicle.position[1] = 4.0  # the middle lane, heading along the road
    x = unwrapped.vehicle.position[0]

    def readings(ahead, lane):
        unwrapped.road.objects = [Obstacle(unwrapped.road, [x + ahead, 4.0 * lane])]
        return unwrapped.observation_type.observe()

    next_lane = readings(distance, 0)
    candidates = [*np.arange(distance - 3.0, distance + 3.0, 0.02), 60.0]
    own_lane = np.array([readings(ahead, 1) for ahead in candidates])
    env.close()
    return float(np.abs(own_lane - next_lane).max(axis=1).min())


def test_v1_tells_the_next_lane_from_the_own_lane_where_v0_cannot():
    # -v0's 16 rays (22.5 deg): an obstacle in the next lane reads as one in the car's own lane while it is more
    # than about 20 m ahead, and as no obstacle at all from there to about 15 m (hidden behind the road edge's readings):
    # a lane change (about 28 m at 20 m/s) has to start before the lidar says which lane to leave.
    for distance in (17.0, 30.0, 45.0):
        assert closest_own_lane_readings("sb3_adc/HighwayObstacle-v0", distance) < 1e-3
    assert closest_own_lane_readings("sb3_adc/HighwayObstacle-v0", 12.0) > 0.05
    # -v1's 64 rays (5.6 deg) tell them apart up to the lidar's range.
    for distance in (12.0, 17.0, 30.0, 45.0):
        assert closest_own_lane_readings("sb3_adc/HighwayObstacle-v1", distance) > 0.05


def drive_knowing_rows(look_ahead: float, seeds: range) -> float:
    """
    Success rate of a controller that is told, ``look_ahead`` metres before each row of obstacles, which lanes it
    blocks (not what the lidar says), and then steers to the nearest free lane: how early a policy must know.
    """
    env = make()
    unwrapped = env.unwrapped
    lane_width = 4.0
    successes = []
    for seed in seeds:
        env.reset(seed=seed)
        goal = None
        while True:
            x, y = unwrapped.vehicle.position
            ahead = [o.position for o in unwrapped.road.objects if -3.0 < o.position[0] - x < look_ahead]
            if ahead:
                row = min(position[0] for position in ahead)
                blocked = {round(position[1] / lane_width) for position in ahead if abs(position[0] - row) < 1.0}
                free = [lane for lane in range(unwrapped.config["lanes_count"]) if lane not in blocked]
                goal = min(free, key=lambda lane: abs(lane * lane_width - y))
            target = round(y / lane_width) if goal is None else goal
            heading = np.clip(0.08 * (target * lane_width - y), -0.35, 0.35)
            steering = np.clip((heading - unwrapped.vehicle.heading) / math.radians(6.0), -1.0, 1.0)
            _, _, terminated, truncated, info = env.step(np.array([steering], dtype=np.float32))
            if terminated or truncated:
                successes.append(info["is_success"])
                break
    env.close()
    return float(np.mean(successes))


def test_the_task_is_solvable_when_the_blocked_lanes_are_known_30_m_ahead():
    # Solvable: told which lanes a row blocks 30 m before it, a simple controller drives every road to the end.
    # Told only 15 m before (where -v0's lidar first tells the next lane from the own lane), it crashes.
    assert drive_knowing_rows(30.0, range(5)) == 1.0
    assert drive_knowing_rows(15.0, range(5)) == 0.0


def test_v1_is_v0_with_64_rays():
    v0, v1 = gym.make("sb3_adc/HighwayObstacle-v0"), gym.make("sb3_adc/HighwayObstacle-v1")
    assert v0.observation_space.shape == (16,)
    assert v1.observation_space.shape == (64,)
    assert gym.spec("sb3_adc/HighwayObstacle-v1").max_episode_steps == 200
    config0, config1 = v0.unwrapped.config, v1.unwrapped.config
    assert config1["observation"] == {**config0["observation"], "cells": 64}
    assert {k: v for k, v in config1.items() if k != "observation"} == {k: v for k, v in config0.items() if k != "observation"}
    obs0, _ = v0.reset(seed=5)
    obs1, _ = v1.reset(seed=5)
    assert [tuple(o.position) for o in v0.unwrapped.road.objects] == [tuple(o.position) for o in v1.unwrapped.road.objects]
    np.testing.assert_array_equal(obs1[::4], obs0)  # every fourth ray of -v1 is a ray of -v0
    # An observation config without `cells` keeps the id's number of rays.
    other = gym.make("sb3_adc/HighwayObstacle-v1", config={"observation": {"type": "RoadEdgeLidarObservation"}})
    assert other.reset(seed=0)[0].shape == (64,)
    for env in (v0, v1, other):
        env.close()


def test_every_obstacle_row_leaves_a_lane_free():
    env = make({"lanes_count": 3, "max_blocked_lanes": 2})
    for seed in range(5):
        env.reset(seed=seed)
        rows = {}
        for obstacle in env.unwrapped.road.objects:
            rows.setdefault(obstacle.position[0], set()).add(obstacle.position[1])
        assert len(rows) > 10
        assert all(1 <= len(lanes) <= 2 for lanes in rows.values())
        gaps = np.diff(sorted(rows))
        assert gaps.min() >= 45.0
        assert gaps.max() <= 75.0
    env.close()


def test_seeding_reproduces_the_obstacles_and_the_observations():
    actions = np.random.default_rng(0).uniform(-1, 1, size=(30, 1)).astype(np.float32)

    def rollout(seed):
        env = make()
        observations = [env.reset(seed=seed)[0]]
        for action in actions:
            obs, _, terminated, truncated, _ = env.step(action)
            observations.append(obs)
            if terminated or truncated:
                break
        positions = [tuple(o.position) for o in env.unwrapped.road.objects]
        env.close()
        return np.array(observations), positions

    first, second, other = rollout(3), rollout(3), rollout(4)
    np.testing.assert_array_equal(first[0], second[0])
    assert first[1] == second[1]
    assert first[1] != other[1]


@pytest.mark.parametrize("sdl_video_driver", [None, "dummy"])
def test_headless_rgb_array_rendering(monkeypatch, sdl_video_driver):
    if sdl_video_driver is None:
        monkeypatch.delenv("SDL_VIDEODRIVER", raising=False)
    else:
        monkeypatch.setenv("SDL_VIDEODRIVER", sdl_video_driver)
    env = make(render_mode="rgb_array")
    env.reset(seed=0)
    env.step(STRAIGHT)
    frame = env.render()
    assert frame.dtype == np.uint8
    assert frame.shape == (150, 600, 3)
    assert frame.std() > 0
    env.close()


@pytest.mark.parametrize(
    ("config", "key"),
    [
        ({"lanes_count": 1}, "lanes_count"),
        ({"max_blocked_lanes": 3}, "max_blocked_lanes"),
        ({"obstacle_gap": [80.0, 40.0]}, "obstacle_gap"),
        ({"ego_speed": 0.0}, "ego_speed"),
        ({"action": {"type": "ContinuousAction", "longitudinal": True, "lateral": True}}, "action"),
        ({"observation": {"type": "Kinematics"}}, "observation"),
    ],
)
def test_invalid_configurations_are_named(config, key):
    with pytest.raises(ValueError, match=f"config\\['{key}'\\]"):
        HighwayObstacleEnv(config=config)


def test_the_best_model_can_be_picked_by_success(tmp_path):
    """``--best-model-metric success`` works on the highway task: its evaluations record a success rate."""
    import pandas as pd

    from sb3_adc.experiment import TrainSettings, train
    from sb3_adc.experiment.layout import RunLayout
    from sb3_adc.experiment.results import evaluation_rows

    settings = TrainSettings(
        algo="ddpg",
        env_id="sb3_adc/HighwayObstacle-v0",
        overrides={"learning_starts": 50, "batch_size": 8, "policy_kwargs": "dict(net_arch=[8])"},
        env_kwargs={"config": {**NO_OBSTACLES, "duration": 4.0}},
        n_timesteps=60,
        eval_freq=30,
        eval_episodes=1,
        final_eval_episodes=1,
        log_folder=str(tmp_path),
        best_model_metric="success",
    )
    result = train(settings)
    rows = pd.DataFrame(evaluation_rows(RunLayout(result.run_dir, settings.env_id), "ddpg", 0))
    assert rows["success_rate"].notna().all()
    assert (Path(result.run_dir) / "best_model.zip").is_file()
