"""Hostile and unusual inputs for courses: wrong `course` types, YAML 1.2 numbers, aliases, huge files."""

from __future__ import annotations

import pytest

from sb3_adc_envs.lidar_course import CourseError, LidarObstacleCourseEnv, load_course
from sb3_adc_envs.lidar_course.course import MAX_COURSE_FILE_BYTES

COURSE = """
corridor:
  width: 1.4
  centerline: [[0, 0], [8, 0], [8, 6], [0, 6]]
  corner_radius: 1.5
start: {{x: {x}, y: 0.0, heading_deg: 0.0}}
"""


@pytest.mark.parametrize("course", [None, 123, 4.5, ["training"], {"name": "x"}])
def test_a_course_of_the_wrong_type_names_the_parameter_and_what_it_accepts(course):
    with pytest.raises(TypeError, match="`course` must be a shipped course name") as error:
        LidarObstacleCourseEnv(course=course)
    assert "procedural" in str(error.value)
    assert type(course).__name__ in str(error.value)


@pytest.mark.parametrize(("written", "value"), [("4e0", 4.0), ("40e-1", 4.0), ("+4E0", 4.0), ("4.0e0", 4.0)])
def test_exponent_numbers_without_a_dot_are_numbers_as_in_yaml_1_2(tmp_path, written, value):
    path = tmp_path / "course.yml"
    path.write_text(COURSE.format(x=written))
    assert load_course(path).start.x == value


def test_a_huge_coordinate_is_out_of_range_not_a_string(tmp_path):
    path = tmp_path / "course.yml"
    path.write_text(COURSE.format(x="-1e300"))
    with pytest.raises(CourseError, match="out of range") as error:
        load_course(path)
    assert error.value.field == "start.x"
    assert "not a number" not in str(error.value)


def test_strings_stay_strings(tmp_path):
    path = tmp_path / "course.yml"
    path.write_text(COURSE.format(x="e300"))
    with pytest.raises(CourseError, match="must be a number, got 'e300'"):
        load_course(path)


def test_yaml_aliases_are_refused_before_they_expand(tmp_path):
    bomb = "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
    bomb += "c: [*b, *b, *b, *b, *b, *b, *b, *b, *b]\n"
    path = tmp_path / "course.yml"
    path.write_text(bomb + COURSE.format(x=4.0))
    with pytest.raises(CourseError, match="aliases") as error:
        load_course(path)
    assert error.value.field == "<file>"
    assert len(str(error.value)) < 1_000


def test_a_file_larger_than_the_bound_is_refused_unread(tmp_path):
    path = tmp_path / "course.yml"
    path.write_text(COURSE.format(x=4.0) + "#" * MAX_COURSE_FILE_BYTES)
    with pytest.raises(CourseError, match="at most") as error:
        load_course(path)
    assert error.value.field == "<file>"
