"""Procedural courses and sb3_adc/LidarObstacleCourse-v1: layouts from seeds, the passable-gap guarantee, held-out seeds."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sb3_adc_envs  # noqa: F401 (registers the environments)
from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv
from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS, TRAIN_LAYOUT_SEEDS, VALIDATION_LAYOUT_SEEDS
from sb3_adc_envs.lidar_course.passability import blocked_corridor_point
from sb3_adc_envs.lidar_course.procedural import CourseGenerator
from sb3_adc_envs.registration import V1_N_RAYS


def test_a_layout_seed_names_one_layout():
    generator = CourseGenerator()
    first, again, other = generator.generate(7), generator.generate(7), generator.generate(8)
    np.testing.assert_array_equal(first.walls, again.walls)
    assert first.obstacles == again.obstacles
    assert first.walls.shape != other.walls.shape or not np.allclose(first.walls, other.walls)


def test_layouts_stay_within_the_stated_ranges_and_vary():
    generator = CourseGenerator()
    courses = [generator.generate(seed) for seed in range(20)]
    widths = [course.corridor.width for course in courses]
    assert all(generator.width[0] <= width <= generator.width[1] for width in widths)
    assert max(widths) - min(widths) > 0.3
    counts = [len(course.obstacles) for course in courses]
    assert max(counts) <= generator.n_obstacles[1]
    assert len(set(counts)) > 1
    assert {obstacle.shape for course in courses for obstacle in course.obstacles} == {"box", "cylinder", "wall"}


@pytest.mark.parametrize("robot_radius", [0.15, 0.3])
def test_every_layout_leaves_a_gap_wider_than_the_robot(robot_radius):
    # The guarantee is by construction; the flood fill of the free space checks it independently.
    generator = CourseGenerator()
    for seed in range(25):
        course = generator.generate(seed, robot_radius)
        assert blocked_corridor_point(course, robot_radius) is None, seed


def test_generator_options_are_validated_where_they_are_defined():
    with pytest.raises(ValueError, match="`width`"):
        CourseGenerator(width=(2.0, 1.0))
    with pytest.raises(ValueError, match=r"`n_obstacles`.*integers"):
        CourseGenerator(n_obstacles=(1.5, 3))
    with pytest.raises(ValueError, match="`gap_margin`"):
        CourseGenerator(gap_margin=-0.1)
    with pytest.raises(ValueError, match="`width`: the narrowest corridor"):
        LidarObstacleCourseEnv(course="procedural", generator=CourseGenerator(width=(0.5, 1.0)))


def test_v1_is_procedural_with_its_rays_and_v0_is_unchanged():
    v1 = gym.make("sb3_adc/LidarObstacleCourse-v1")
    assert v1.spec.max_episode_steps == 500
    assert v1.observation_space.shape == (V1_N_RAYS,)
    assert v1.unwrapped.procedural
    assert v1.unwrapped.layout_seeds == TRAIN_LAYOUT_SEEDS
    v0 = gym.make("sb3_adc/LidarObstacleCourse-v0")
    assert v0.observation_space.shape == (8,)
    assert not v0.unwrapped.procedural
    assert v0.unwrapped.course.name == "training"
    noisy = gym.make("sb3_adc/LidarObstacleCourseNoisy-v1")
    assert noisy.observation_space.shape == (V1_N_RAYS,)
    assert noisy.unwrapped.procedural
    for env in (v1, v0, noisy):
        env.close()


def test_reset_seed_gives_the_same_layout_and_observations():
    env = gym.make("sb3_adc/LidarObstacleCourse-v1")
    layouts = []
    for seed in (3, 4, 3):
        obs, info = env.reset(seed=seed)
        layouts.append((env.unwrapped.layout_seed, info["course"], obs.copy()))
    assert layouts[0][0] == layouts[2][0]
    assert layouts[0][1] == layouts[2][1]
    np.testing.assert_array_equal(layouts[0][2], layouts[2][2])
    assert layouts[0][0] != layouts[1][0]
    env.close()


def test_layouts_are_drawn_from_the_training_range_and_held_out_seeds_are_disjoint():
    assert TRAIN_LAYOUT_SEEDS[1] <= TEST_LAYOUT_SEEDS[0]
    assert TEST_LAYOUT_SEEDS[1] <= VALIDATION_LAYOUT_SEEDS[0]
    env = LidarObstacleCourseEnv(course="procedural")
    seen = set()
    env.reset(seed=0)
    for _ in range(10):
        env.reset()
        seen.add(env.layout_seed)
    assert len(seen) == 10
    assert all(TRAIN_LAYOUT_SEEDS[0] <= seed < TRAIN_LAYOUT_SEEDS[1] for seed in seen)
    test_env = LidarObstacleCourseEnv(course="procedural", layout_seeds=TEST_LAYOUT_SEEDS)
    test_env.reset(seed=0)
    assert TEST_LAYOUT_SEEDS[0] <= test_env.layout_seed < TEST_LAYOUT_SEEDS[1]
    test_env.reset(options={"layout_seed": 5})
    assert test_env.layout_seed == 5
    assert test_env.course.name == "procedural-5"
    env.close()
    test_env.close()


def test_layout_seed_option_and_layout_seeds_are_validated():
    with pytest.raises(ValueError, match="`layout_seeds`"):
        LidarObstacleCourseEnv(course="procedural", layout_seeds=(5, 5))
    env = LidarObstacleCourseEnv(course="procedural")
    with pytest.raises(ValueError, match="layout_seed"):
        env.reset(options={"layout_seed": -1})
    env.close()
    fixed = LidarObstacleCourseEnv(course="training")
    with pytest.raises(ValueError, match="procedural courses"):
        fixed.reset(options={"layout_seed": 1})
    fixed.close()


def test_a_new_layout_rebuilds_the_world_the_lidar_sees():
    env = LidarObstacleCourseEnv(course="procedural")
    env.reset(options={"layout_seed": 1})
    first_obstacles = len(env.simulation.obstacle_ids)
    assert first_obstacles == len(env.course.obstacles) > 0
    env.reset(options={"layout_seed": 2})
    assert len(env.simulation.obstacle_ids) == len(env.course.obstacles)
    assert len(env.simulation.wall_ids) == len(env.course.walls)
    env.close()


def test_a_generator_given_lists_behaves_as_one_given_tuples():
    from_lists = CourseGenerator(width=[1.4, 1.6], n_obstacles=[2, 3])
    assert from_lists == CourseGenerator(width=(1.4, 1.6), n_obstacles=(2, 3))
    env = LidarObstacleCourseEnv(course="procedural", generator=from_lists)
    env.reset(seed=1)
    assert 1.4 <= env.course.corridor.width <= 1.6
    assert 2 <= len(env.course.obstacles) <= 3
    env.close()
