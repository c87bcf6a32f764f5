"""The lidar reads the distances to the walls pybullet sees, from the robot's centre, never the robot itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv
from sb3_adc_envs.lidar_course.course_parsing import course_from_dict

SIZE = 10.0
WALL_THICKNESS = 0.1  # of the `box_course` fixture
LOW, HIGH = WALL_THICKNESS / 2.0, SIZE - WALL_THICKNESS / 2.0  # the box's inner faces


def expected_reading(x: float, y: float, angle: float, max_range: float) -> float:
    """Distance from (x, y) along `angle` to the inner faces of the box course, divided by max_range, capped at 1."""
    dx, dy = math.cos(angle), math.sin(angle)
    candidates = []
    if dx > 1e-12:
        candidates.append((HIGH - x) / dx)
    if dx < -1e-12:
        candidates.append((LOW - x) / dx)
    if dy > 1e-12:
        candidates.append((HIGH - y) / dy)
    if dy < -1e-12:
        candidates.append((LOW - y) / dy)
    return min(min(candidates) / max_range, 1.0)


@pytest.mark.parametrize(
    ("x", "y", "heading_deg"),
    [(8.0, 5.0, 0.0), (5.0, 8.5, 90.0), (1.2, 1.7, 200.0), (8.6, 8.1, 45.0), (2.0, 7.0, -30.0), (9.0, 1.0, 123.0)],
)
def test_readings_match_the_distance_to_the_walls(box_course, x, y, heading_deg):
    env = LidarObstacleCourseEnv(course=box_course(SIZE, (x, y, heading_deg)), max_range=3.0)
    obs, _ = env.reset()
    heading = math.radians(heading_deg)
    expected = [expected_reading(x, y, heading + offset, 3.0) for offset in env.ray_angles]
    np.testing.assert_allclose(obs, expected, atol=1e-4)
    assert np.any(obs < 1.0)  # each pose is within range of some wall
    env.close()


def test_robot_facing_a_wall_reads_its_distance(box_course):
    # Facing the wall x = 9.95 from 1.5 m away: the forward ray reads 1.5 m.
    env = LidarObstacleCourseEnv(course=box_course(SIZE, (HIGH - 1.5, 5.0, 0.0)), max_range=2.0)
    obs, _ = env.reset()
    assert obs[0] == pytest.approx(1.5 / 2.0, abs=1e-4)
    # One step of 0.1 m towards it: 1.4 m.
    obs, *_ = env.step(np.zeros(1, dtype=np.float32))
    assert obs[0] == pytest.approx(1.4 / 2.0, abs=1e-4)
    env.close()


@pytest.mark.parametrize("heading_deg", [0.0, 17.0, 90.0, 181.0, -77.0])
def test_rays_never_hit_the_robot(box_course, heading_deg):
    # In the middle of a 20 m box no wall is within 3 m: every ray must read its full length, though all
    # start at the robot's centre, inside its body.
    env = LidarObstacleCourseEnv(course=box_course(20.0, (10.0, 10.0, heading_deg)), max_range=3.0)
    obs, _ = env.reset()
    np.testing.assert_array_equal(obs, np.ones(8, dtype=np.float32))
    for _ in range(20):
        obs, *_ = env.step(np.array([0.7], dtype=np.float32))
        np.testing.assert_array_equal(obs, np.ones(8, dtype=np.float32))
    env.close()


def test_rays_turn_with_the_robot(box_course):
    # The wall is ahead at heading 0; after turning to heading 90 deg it is on the robot's right (ray at -90 deg).
    course = box_course(SIZE, (HIGH - 1.0, 5.0, 0.0))
    env = LidarObstacleCourseEnv(course=course, max_range=2.0)
    ahead, _ = env.reset()
    turned, _ = env.reset(options={"start_pose": (HIGH - 1.0, 5.0, 90.0)})
    right = 6  # ray angles 0, 45, ..., 315 deg: index 6 points at -90 deg
    assert ahead[0] == pytest.approx(0.5, abs=1e-4)
    assert turned[right] == pytest.approx(0.5, abs=1e-4)
    assert turned[0] == 1.0
    env.close()


def test_field_of_view_spreads_the_rays(box_course):
    env = LidarObstacleCourseEnv(course=box_course(), n_rays=5, fov_deg=180.0)
    np.testing.assert_allclose(np.degrees(env.ray_angles), [-90.0, -45.0, 0.0, 45.0, 90.0])
    assert env.observation_space.shape == (5,)
    env.close()
    env = LidarObstacleCourseEnv(course=box_course(), n_rays=8)
    np.testing.assert_allclose(np.degrees(env.ray_angles), np.arange(8) * 45.0)
    env.close()


@pytest.mark.parametrize(("n_rays", "fov_deg", "rays_per_reading"), [(8, 360.0, 2), (24, 360.0, 4), (5, 180.0, 3)])
@pytest.mark.parametrize(("x", "y", "heading_deg"), [(8.0, 5.0, 0.0), (1.2, 1.7, 200.0), (8.6, 8.1, 45.0)])
def test_a_reading_of_several_rays_is_the_nearest_over_its_sector(
    box_course, n_rays, fov_deg, rays_per_reading, x, y, heading_deg
):
    env = LidarObstacleCourseEnv(
        course=box_course(SIZE, (x, y, heading_deg)), n_rays=n_rays, fov_deg=fov_deg, rays_per_reading=rays_per_reading
    )
    obs, _ = env.reset()
    assert obs.shape == env.observation_space.shape == (n_rays,)
    # The sector is the angle between neighbouring readings; its rays sit at the middles of its equal parts.
    sector = math.radians(360.0 / n_rays if fov_deg == 360.0 else fov_deg / (n_rays - 1))
    parts = (np.arange(rays_per_reading) + 0.5) / rays_per_reading * sector - sector / 2.0
    heading = math.radians(heading_deg)
    expected = [min(expected_reading(x, y, heading + angle + part, 3.0) for part in parts) for angle in env.ray_angles]
    np.testing.assert_allclose(obs, expected, atol=1e-4)
    env.close()


@pytest.mark.parametrize(("rays_per_reading", "shown"), [(1, False), (4, True)])
def test_several_rays_per_reading_show_a_post_between_two_readings(rays_per_reading, shown):
    # A post of 5 cm radius 1.3 m ahead and 7.5 degrees to the left, midway between the 24 readings at 0 and
    # 15 degrees: both of their single rays pass 17 cm beside it; with four rays per reading (3.75 degrees apart)
    # the nearest pass 4.3 cm from its centre, through it.
    data = {
        "name": "box with a post",
        "wall_thickness": WALL_THICKNESS,
        "walls": [[[0.0, 0.0], [SIZE, 0.0], [SIZE, SIZE], [0.0, SIZE], [0.0, 0.0]]],
        "start": {"x": 5.0, "y": 5.0, "heading_deg": 0.0},
        "obstacles": [{"shape": "cylinder", "position": [6.3, 5.0 + 1.3 * math.tan(math.radians(7.5))], "radius": 0.05}],
    }
    env = LidarObstacleCourseEnv(course=course_from_dict(data), n_rays=24, rays_per_reading=rays_per_reading)
    obs, _ = env.reset()
    post = env.simulation.obstacle_ids[0]
    assert (post in env.simulation.ray_bodies) == shown
    distance = math.hypot(1.3, 1.3 * math.tan(math.radians(7.5))) - 0.05
    if shown:
        assert min(obs[:2]) == pytest.approx(distance / 3.0, abs=0.01)
    else:
        # Past the post the two rays meet the far wall, 4.95 m away: beyond the 3 m range.
        np.testing.assert_array_equal(obs[:2], [1.0, 1.0])
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"rays_per_reading": 0}, "rays_per_reading"),
        ({"rays_per_reading": 17}, "rays_per_reading"),
        ({"rays_per_reading": 2.0}, "rays_per_reading"),
        ({"rays_per_reading": True}, "rays_per_reading"),
        ({"n_rays": 0}, "n_rays"),
        ({"fov_deg": 0.0}, "fov_deg"),
        ({"fov_deg": 400.0}, "fov_deg"),
        ({"max_range": -1.0}, "max_range"),
        ({"speed": 0.0}, "speed"),
        ({"robot_radius": float("nan")}, "robot_radius"),
        ({"max_steer_deg": 0.0}, "max_steer_deg"),
        ({"start_position_jitter": -0.1}, "start_position_jitter"),
        ({"start_heading_jitter_deg": float("inf")}, "start_heading_jitter_deg"),
        ({"render_mode": "human"}, "render_mode"),
    ],
)
def test_invalid_parameters_are_named(box_course, kwargs, parameter):
    with pytest.raises(ValueError, match=f"`{parameter}`"):
        LidarObstacleCourseEnv(course=box_course(), **kwargs)


def test_the_wheeled_robot_reads_several_rays_per_reading_as_the_kinematic_one():
    # At the start both robots stand at the same pose: the same lidar gives the same readings from either body.
    import gymnasium as gym

    readings = {}
    for robot in ("kinematic", "wheeled"):
        env = gym.make("sb3_adc/LidarObstacleCourse-v1", robot=robot, rays_per_reading=4)
        readings[robot], _ = env.reset(seed=0, options={"layout_seed": 1_000_003})
        env.close()
    assert readings["kinematic"].shape == (24,)
    np.testing.assert_allclose(readings["wheeled"], readings["kinematic"], atol=1e-4)
    single = gym.make("sb3_adc/LidarObstacleCourse-v1")
    one_ray, _ = single.reset(seed=0, options={"layout_seed": 1_000_003})
    single.close()
    # The four rays of a reading meet what its one ray passes: a different scan of the same pose.
    assert not np.array_equal(one_ray, readings["kinematic"])
