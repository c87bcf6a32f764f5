"""Course files: the shipped courses, loading by name or path, and errors that name the file and the field."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from sb3_adc_envs.lidar_course import CourseError, LidarObstacleCourseEnv, load_course, shipped_courses
from sb3_adc_envs.lidar_course.course import COURSES_DIR
from sb3_adc_envs.lidar_course.course_parsing import course_from_dict

UNSEEN = ("unseen_arena", "unseen_narrow", "unseen_wide", "unseen_zigzag")

VALID = {
    "name": "loop",
    "corridor": {"width": 1.4, "centerline": [[0.0, 0.0], [8.0, 0.0], [8.0, 6.0], [0.0, 6.0]], "corner_radius": 1.5},
    "start": {"x": 4.0, "y": 0.0, "heading_deg": 0.0},
}
CENTRE_OF_BOX = {"x": 5, "y": 5, "heading_deg": 0}


def write(tmp_path, data, name="course.yml"):
    path = tmp_path / name
    path.write_text(json.dumps(data) if name.endswith(".json") else yaml.safe_dump(data))
    return path


def with_changes(**changes):
    """A deep copy of VALID with some top-level keys replaced (None removes the key)."""
    data = json.loads(json.dumps(VALID))
    for key, value in changes.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    return data


def test_the_training_course_and_at_least_three_unseen_layouts_ship():
    names = shipped_courses()
    assert "training" in names
    assert set(UNSEEN) <= set(names)


@pytest.mark.parametrize("name", ["training", *UNSEEN])
def test_every_shipped_course_loads_and_fits_the_default_robot(name):
    course = load_course(name)
    assert course.name == name
    assert course.walls.shape[1] == 4
    assert len(course.walls) >= 4
    course.check_robot_fits(0.15)
    env = LidarObstacleCourseEnv(course=name)
    obs, _ = env.reset()
    assert np.all((obs >= 0.0) & (obs <= 1.0))
    env.close()


def test_unseen_layouts_change_the_path_and_the_width():
    training = load_course("training")
    widths = {name: load_course(name).corridor.width for name in UNSEEN if load_course(name).corridor is not None}
    assert min(widths.values()) < training.corridor.width < max(widths.values())
    for name in UNSEEN:
        course = load_course(name)
        same_walls = course.walls.shape == training.walls.shape and np.allclose(course.walls, training.walls)
        assert not same_walls


def test_a_course_loads_from_a_yaml_or_json_path(tmp_path):
    from_yaml = load_course(write(tmp_path, VALID))
    from_json = load_course(str(write(tmp_path, VALID, "course.json")))
    np.testing.assert_allclose(from_yaml.walls, from_json.walls)
    assert from_yaml.start.heading == 0.0
    assert from_yaml.corridor.width == 1.4
    env = LidarObstacleCourseEnv(course=str(tmp_path / "course.yml"))
    assert env.course.name == "loop"
    env.close()


def test_the_corridor_walls_leave_the_free_width(tmp_path):
    # A straight stretch of the loop: the wall faces are width/2 on both sides of the centre line.
    course = load_course(write(tmp_path, VALID))
    assert course.clearance(4.0, 0.0) == pytest.approx(0.7)
    assert course.clearance(4.0, 0.6) == pytest.approx(0.1)


def test_the_shipped_course_files_are_plain_data():
    # Shipped files parse with a safe loader: no tags, no code.
    for path in COURSES_DIR.glob("*.yml"):
        assert isinstance(yaml.safe_load(path.read_text()), dict), path


@pytest.mark.parametrize(
    ("data", "field", "message"),
    [
        (with_changes(start=None), "start", "missing"),
        (with_changes(start={"x": 4.0, "y": 0.0}), "start.heading_deg", "missing"),
        (with_changes(start={"x": "four", "y": 0.0, "heading_deg": 0.0}), "start.x", "must be a number"),
        (with_changes(start={"x": True, "y": 0.0, "heading_deg": 0.0}), "start.x", "must be a number"),
        (with_changes(corridor=None), "corridor", "neither is given"),
        (with_changes(corridor={"centerline": VALID["corridor"]["centerline"]}), "corridor.width", "missing"),
        (with_changes(corridor={**VALID["corridor"], "width": "wide"}), "corridor.width", "must be a number"),
        (with_changes(corridor={**VALID["corridor"], "width": -1.0}), "corridor.width", "must be > 0"),
        (
            with_changes(corridor={**VALID["corridor"], "centerline": [[0, 0], [8, "x"], [8, 6]]}),
            "corridor.centerline[1][1]",
            "must be a number",
        ),
        (with_changes(corridor={**VALID["corridor"], "centerline": [[0, 0], [8, 0]]}), "corridor.centerline", "at least 3"),
        (with_changes(corridor={**VALID["corridor"], "corner_radius": 5.0}), "corridor.corner_radius", "too large"),
        (with_changes(corridor={**VALID["corridor"], "bend": 1}), "corridor", "unknown key"),
        (with_changes(wall_thickness=0), "wall_thickness", "must be > 0"),
        (with_changes(colour="red"), "<root>", "unknown key"),
        # A loop that comes back within its own width: the corridor overlaps itself.
        (
            with_changes(corridor={"width": 1.4, "centerline": [[0, 0], [8, 0], [8, 1.0], [0, 1.0]]}),
            "corridor.centerline",
            "overlaps itself",
        ),
        # The start pose outside the corridor.
        (with_changes(start={"x": 4.0, "y": 3.0, "heading_deg": 0.0}), "start", "outside the corridor"),
        # Open geometry: wall polylines that do not close around the start.
        (
            with_changes(corridor=None, walls=[[[0, 0], [10, 0], [10, 10], [0, 10]]], start=CENTRE_OF_BOX),
            "walls",
            "open geometry",
        ),
        (with_changes(walls=[[[1, 1]]]), "walls[0]", "at least 2"),
        (with_changes(walls="none"), "walls", "polylines"),
    ],
)
def test_invalid_course_files_name_the_file_and_the_field(tmp_path, data, field, message):
    path = write(tmp_path, data)
    with pytest.raises(CourseError, match=message) as error:
        load_course(path)
    assert error.value.field == field
    assert str(path) in str(error.value)
    assert f"`{field}`" in str(error.value)


def test_a_start_pose_overlapping_a_wall_is_rejected(tmp_path):
    # The start is inside the corridor, but 0.1 m from a wall face: a robot of radius 0.15 m overlaps it.
    path = write(tmp_path, with_changes(start={"x": 4.0, "y": 0.6, "heading_deg": 0.0}))
    course = load_course(path)
    with pytest.raises(CourseError, match="overlaps a wall") as error:
        LidarObstacleCourseEnv(course=course)
    assert error.value.field == "start"
    assert str(path) in str(error.value)
    course.check_robot_fits(0.05)  # a smaller robot fits


def test_a_corridor_too_narrow_for_the_robot_is_rejected(tmp_path):
    course = load_course(write(tmp_path, with_changes(corridor={**VALID["corridor"], "width": 0.25})))
    with pytest.raises(CourseError, match="too narrow") as error:
        course.check_robot_fits(0.15)
    assert error.value.field == "corridor.width"


def test_a_closed_wall_polyline_around_the_start_is_a_valid_course(tmp_path):
    closed_box = [[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]]
    data = with_changes(corridor=None, walls=[closed_box], start={**CENTRE_OF_BOX, "heading_deg": 90})
    course = load_course(write(tmp_path, data))
    assert len(course.walls) == 4
    assert course.corridor is None
    assert course.start.heading == pytest.approx(math.pi / 2)


def test_unknown_courses_and_unreadable_files(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"`course`.*training"):
        load_course("no_such_course")
    bad = tmp_path / "broken.yml"
    bad.write_text("start: [unclosed")
    with pytest.raises(CourseError, match="cannot be parsed") as error:
        load_course(bad)
    assert str(bad) in str(error.value)
    text = tmp_path / "course.txt"
    text.write_text(yaml.safe_dump(VALID))
    with pytest.raises(CourseError, match="unknown file type"):
        load_course(text)
    with pytest.raises(CourseError, match="must be a mapping"):
        load_course(write(tmp_path, [1, 2, 3]))


def test_course_objects_can_be_built_in_memory():
    course = course_from_dict(VALID)
    assert course.source == "<course>"
    env = LidarObstacleCourseEnv(course=course)
    env.reset()
    env.close()
