"""Obstacles in course files: parsing, validation, the bodies the lidar sees and the robot hits, shipped courses."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from sb3_adc_envs.lidar_course import CourseError, LidarObstacleCourseEnv, load_course, shipped_courses
from sb3_adc_envs.lidar_course.course_parsing import course_from_dict
from sb3_adc_envs.lidar_course.passability import kinematic_reach

OBSTACLE_COURSES = ("unseen_posts", "unseen_slalom", "unseen_stubs")
STRAIGHT = np.zeros(1, dtype=np.float32)

# A 14 m x 8 m rectangular loop 2 m wide; the robot starts at (3, 0) heading +x along the bottom straight.
LOOP = {
    "name": "loop",
    "corridor": {"width": 2.0, "centerline": [[0, 0], [14, 0], [14, 8], [0, 8]], "corner_radius": 1.6},
    "start": {"x": 3.0, "y": 0.0, "heading_deg": 0.0},
}


def loop_with(*obstacles, **changes):
    return {**json.loads(json.dumps(LOOP)), "obstacles": list(obstacles), **changes}


def write(tmp_path, data):
    path = tmp_path / "course.yml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_each_shape_parses_with_its_size_and_orientation():
    course = course_from_dict(
        loop_with(
            {"shape": "box", "position": [7, 0.3], "size": [0.4, 0.6], "yaw_deg": 90},
            {"shape": "cylinder", "position": [10, -0.2], "radius": 0.25},
            {"shape": "wall", "position": [14.5, 4], "length": 0.8},
            {"shape": "wall", "position": [7, 8.5], "length": 0.8, "thickness": 0.2, "yaw_deg": 90},
        )
    )
    box, cylinder, stub, thick_stub = course.obstacles
    assert (box.shape, box.length, box.width, box.yaw) == ("box", 0.4, 0.6, pytest.approx(math.pi / 2))
    # The box is turned by 90 degrees: it reaches 0.3 m along x and 0.2 m along y from its centre.
    assert box.distance(7.3, 0.3) == pytest.approx(0.0)
    assert box.distance(7.0, 0.6) == pytest.approx(0.1)
    assert (cylinder.shape, cylinder.length) == ("cylinder", 0.5)
    assert stub.width == 0.1  # a stub is as thick as the walls unless told
    assert thick_stub.width == 0.2
    # Clearance counts the obstacles: 0.25 m from the cylinder's surface.
    assert course.clearance(10.0, -0.7) == pytest.approx(0.25)


@pytest.mark.parametrize(
    ("obstacle", "field", "message"),
    [
        ({"shape": "cone", "position": [7, 0]}, "obstacles[0].shape", "box, cylinder, wall"),
        ({"position": [7, 0], "radius": 0.2}, "obstacles[0].shape", "must be one of"),
        ({"shape": "cylinder", "position": [7, 0]}, "obstacles[0].radius", "missing"),
        ({"shape": "box", "position": [7, 0], "size": [0.4]}, "obstacles[0].size", r"\[length, width\]"),
        ({"shape": "box", "position": [7, 0], "size": [0.4, -1]}, "obstacles[0].size[1]", "must be > 0"),
        ({"shape": "cylinder", "position": [7, "a"], "radius": 0.2}, "obstacles[0].position[1]", "must be a number"),
        ({"shape": "cylinder", "position": [7, 0], "radius": 0.2, "size": 1}, "obstacles[0]", "unknown key"),
        ({"shape": "wall", "position": [7, 0], "length": 0.5, "yaw_deg": "up"}, "obstacles[0].yaw_deg", "must be a number"),
        # Outside the corridor: inside the island, and out beyond the outer wall.
        ({"shape": "cylinder", "position": [7, 4], "radius": 0.2}, "obstacles[0].position", "outside the corridor"),
        ({"shape": "cylinder", "position": [7, -3], "radius": 0.2}, "obstacles[0].position", "outside the corridor"),
        # On the start pose, and just too close to it (0.95 m from its surface).
        ({"shape": "cylinder", "position": [3, 0], "radius": 0.2}, "obstacles[0]", "free around the start"),
        ({"shape": "cylinder", "position": [4.15, 0], "radius": 0.2}, "obstacles[0]", "free around the start"),
    ],
)
def test_invalid_obstacles_name_the_file_and_the_field(tmp_path, obstacle, field, message):
    path = write(tmp_path, loop_with(obstacle))
    with pytest.raises(CourseError, match=message) as error:
        load_course(path)
    assert error.value.field == field
    assert str(path) in str(error.value)


def test_obstacles_must_be_a_list(tmp_path):
    with pytest.raises(CourseError, match="must be a list") as error:
        load_course(write(tmp_path, {**LOOP, "obstacles": {"shape": "box"}}))
    assert error.value.field == "obstacles"


def test_an_obstacle_just_far_enough_from_the_start_is_accepted():
    # 1.05 m from the start to the cylinder's surface: past the 1 m kept free (0.95 m is refused above).
    course = course_from_dict(loop_with({"shape": "cylinder", "position": [4.25, 0], "radius": 0.2}))
    (cylinder,) = course.obstacles
    assert cylinder.distance(3.0, 0.0) == pytest.approx(1.05)


def test_obstacles_in_a_walls_only_course_must_be_in_the_start_region(tmp_path):
    arena = {
        "walls": [[[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], [[3, 3], [7, 3], [7, 7], [3, 7], [3, 3]]],
        "start": {"x": 1.5, "y": 1.5, "heading_deg": 0},
    }
    course_from_dict({**arena, "obstacles": [{"shape": "cylinder", "position": [5, 1.5], "radius": 0.2}]})
    with pytest.raises(CourseError, match="outside the free space") as error:
        load_course(write(tmp_path, {**arena, "obstacles": [{"shape": "cylinder", "position": [5, 5], "radius": 0.2}]}))
    assert error.value.field == "obstacles[0].position"


@pytest.mark.parametrize(
    "obstacles",
    [
        # A stub across the whole corridor.
        [{"shape": "wall", "position": [8, 0], "length": 2.2, "yaw_deg": 90}],
        # A cylinder leaving 0.25 m on either side: less than the robot's 0.3 m diameter.
        [{"shape": "cylinder", "position": [8, 0], "radius": 0.75}],
        # Two stubs, each leaving a gap, that close the corridor together (a diagonal barrier).
        [
            {"shape": "wall", "position": [8, -0.4], "length": 1.3, "yaw_deg": 90},
            {"shape": "wall", "position": [8.15, 0.4], "length": 1.3, "yaw_deg": 90},
        ],
    ],
)
def test_obstacles_that_block_the_corridor_are_rejected_for_the_robot(tmp_path, obstacles):
    path = write(tmp_path, loop_with(*obstacles))
    course = load_course(path)  # the file alone is valid: passability depends on the robot
    with pytest.raises(CourseError, match="no way round the corridor") as error:
        LidarObstacleCourseEnv(course=str(path))
    assert error.value.field == "obstacles"
    assert str(path) in str(error.value)
    blocked = np.array([float(v) for v in str(error.value).split("blocked near (")[1].split(")")[0].split(",")])
    assert np.hypot(*(blocked - [8.0, 0.0])) < 1.5  # the message points at the blockage
    assert course.obstacles


def test_a_gap_slightly_wider_than_the_robot_is_passable():
    # The cylinder leaves 0.4 m on either side of it, the robot is 0.3 m wide.
    course = course_from_dict(loop_with({"shape": "cylinder", "position": [8, 0], "radius": 0.6}))
    course.check_robot_fits(0.15)
    with pytest.raises(CourseError, match="no way round"):
        course.check_robot_fits(0.21)


def test_the_lidar_sees_an_obstacle_and_driving_into_it_is_a_collision():
    # A box 1 m wide straight ahead at x = 6 (its face at 5.5): 2.5 m from the start, within the 3 m rays.
    course = course_from_dict(loop_with({"shape": "box", "position": [6, 0], "size": [1.0, 1.0]}))
    env = LidarObstacleCourseEnv(course=course)
    obs, _ = env.reset()
    assert obs[0] == pytest.approx(2.5 / 3.0, abs=1e-3)
    assert env.simulation.ray_bodies[0] == env.simulation.obstacle_ids[0]
    steps, terminated, info = 0, False, {}
    while not terminated:
        _, reward, terminated, _, info = env.step(STRAIGHT)
        steps += 1
    # The rim (radius 0.15) reaches the face at x = 5.5 on the step to x = 5.4 (step 24).
    assert steps == 24
    assert reward == -1.0
    assert info["collision"]
    assert not info["is_success"]
    env.close()


@pytest.mark.parametrize("robot", ["kinematic", "wheeled"])
def test_touching_names_what_the_robot_hits(robot):
    # Along the bottom straight (walls at y = -1 and 1): a cylinder, a box and a wall stub, far apart.
    course = course_from_dict(
        loop_with(
            {"shape": "cylinder", "position": [6, 0], "radius": 0.1},
            {"shape": "box", "position": [9, 0], "size": [0.3, 0.3]},
            {"shape": "wall", "position": [11.5, -0.6], "length": 0.8, "yaw_deg": 90},
        )
    )
    env = LidarObstacleCourseEnv(course=course, robot=robot)
    env.reset()
    simulation, lidar = env.simulation, np.empty(env.n_rays)
    # On the rim of each (robot radius 0.15), clear of them, and against the outer wall plus the stub.
    for (x, y), touched in [
        ((3.0, 0.0), []),
        ((6.2, 0.0), ["cylinder"]),
        ((9.25, 0.0), ["box"]),
        ((11.5, -0.1), ["stub"]),
        ((5.0, -0.9), ["wall"]),
        ((11.5, -0.9), ["stub", "wall"]),
    ]:
        collided = simulation.move_robot(x, y, 0.0, lidar)
        assert sorted(simulation.touching(x, y)) == touched, (x, y)
        # The step's test agrees: a collision exactly where something is touched.
        assert collided == bool(touched)
    # The names of bodies given by id: the obstacles in the course's order, any wall segment "wall".
    assert simulation.body_kinds([*simulation.obstacle_ids, simulation.wall_ids[0]]) == ["cylinder", "box", "stub", "wall"]
    env.close()


def test_the_same_course_without_the_obstacle_lets_the_robot_drive_on():
    env = LidarObstacleCourseEnv(course=course_from_dict(LOOP))
    obs, _ = env.reset()
    assert obs[0] == 1.0
    for _ in range(30):
        _, _, terminated, _, _ = env.step(STRAIGHT)
        assert not terminated
    env.close()


def test_shipped_courses_with_obstacles_load_fit_the_robot_and_are_unseen():
    names = shipped_courses()
    for name in OBSTACLE_COURSES:
        assert name in names
        course = load_course(name)
        assert len(course.obstacles) >= 5
        course.check_robot_fits(0.15)
        env = LidarObstacleCourseEnv(course=name)
        env.reset()
        assert len(env.simulation.obstacle_ids) == len(course.obstacles)
        env.close()
    shapes = {obstacle.shape for name in OBSTACLE_COURSES for obstacle in load_course(name).obstacles}
    assert shapes == {"box", "cylinder", "wall"}
    assert not load_course("training").obstacles  # the paper's training course stays empty


def stub_ahead(distance: float) -> dict:
    # A wall stub across the bottom straight from the lower wall to y = 0.5, `distance` m ahead of the start (3, 0):
    # a 0.5 m gap at the top, wider than the robot's 0.3 m.
    return loop_with({"shape": "wall", "position": [3.0 + distance, -0.275], "length": 1.55, "yaw_deg": 90})


@pytest.mark.parametrize("n_actions", [3, 5])
def test_kinematic_reach_tells_a_gap_the_robot_can_steer_through_from_one_it_only_fits_through(n_actions):
    robot = {"robot_radius": 0.15, "speed": 0.1, "max_steer": math.radians(6.0), "n_actions": n_actions, "max_states": 500}
    near, far = course_from_dict(stub_ahead(1.1)), course_from_dict(stub_ahead(4.1))
    for course in (near, far):
        course.check_robot_fits(0.15)  # both gaps are wide enough for the robot
    # Far ahead, the robot has room to swerve to the gap and straighten before the top wall: it gets past the
    # stub, round the first corner and up the side (120 steps). 1.1 m ahead, its 0.95 m turning radius cannot
    # shift it 0.65 m sideways and back in time: every steering sequence crashes at the stub.
    assert kinematic_reach(far, n_steps=120, **robot) == 120
    reach = kinematic_reach(near, n_steps=120, **robot)
    assert 5 <= reach <= 20
    # The empty loop is drivable; the obstacle-free episodes of the environment agree.
    assert kinematic_reach(course_from_dict(LOOP), n_steps=120, **robot) == 120


def test_kinematic_reach_agrees_with_the_environment_s_collisions():
    # Driving straight at the stub is one of the searched drives: the search's longest drive lasts at least as long
    # as the environment lets the straight one (a step less at most, for the search grid's one-cell margin), and
    # swerving towards the gap buys only a few steps more.
    course = course_from_dict(stub_ahead(1.1))
    env = LidarObstacleCourseEnv(course=course)
    env.reset(seed=0)
    steps = 0
    while True:
        steps += 1
        _, _, terminated, _, info = env.step(STRAIGHT)
        if terminated:
            break
    env.close()
    assert info["collision"]
    reach = kinematic_reach(course, 0.15, 0.1, math.radians(6.0), n_steps=120, max_states=500)
    assert steps - 2 <= reach <= steps + 8


def test_kinematic_reach_checks_its_actions():
    with pytest.raises(ValueError, match="n_actions"):
        kinematic_reach(course_from_dict(LOOP), 0.15, 0.1, 0.1, n_steps=10, n_actions=4)
