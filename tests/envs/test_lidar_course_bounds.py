"""Course files that are small but describe huge courses: every bound is checked fast, before the allocation it sets."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from sb3_adc_envs.lidar_course import CourseError, load_course, shipped_courses
from sb3_adc_envs.lidar_course import course as course_module
from sb3_adc_envs.lidar_course.course import (
    MAX_CENTERLINE_POINTS,
    MAX_COURSE_FILE_BYTES,
    MAX_COURSE_SIDE,
    MAX_OBSTACLES,
    MAX_OVERLAP_CHECK_DISTANCES,
    MAX_WALL_POINTS,
    MAX_WALL_SEGMENTS,
)
from sb3_adc_envs.lidar_course.course_parsing import course_from_dict, with_obstacles
from sb3_adc_envs.lidar_course.course_yaml import MAX_YAML_DEPTH, MAX_YAML_VALUES, flow_depth_exceeds
from sb3_adc_envs.lidar_course.passability import GRID_RESOLUTION, MAX_GRID_CELLS, robot_fits
from sb3_adc_envs.lidar_course.procedural import CourseGenerator

#: Time within which a hostile file must be refused [s]. A valid course loads in milliseconds and the slowest refusal
#: here takes about 0.4 s on an idle core; the inputs these tests guard against took minutes before they were bounded, so
#: the margin is wide enough for a machine whose cores are all busy (e.g. a benchmark beside ``pytest -n 2``).
FAST = 3.0

START = "start: {x: 4.0, y: 0.0, heading_deg: 0.0}\n"


def refused(path_or_data, match: str, *, field: str | None = None, within: float = FAST) -> CourseError:
    """Load a course file (or build a course from a mapping), assert it is refused within ``within`` seconds."""

    def load() -> object:
        if isinstance(path_or_data, dict):
            return course_from_dict(path_or_data, source="hostile.yml")
        return load_course(path_or_data)

    begin = time.perf_counter()
    with pytest.raises(CourseError, match=match) as error:
        load()
    elapsed = time.perf_counter() - begin
    assert elapsed < within, f"refused after {elapsed:.2f} s"
    if field is not None:
        assert error.value.field == field
    assert len(str(error.value)) < 1_000  # the message never echoes the document
    return error.value


def square_corridor(side: float) -> str:
    return f"corridor: {{width: 1.4, centerline: [[0, 0], [{side}, 0], [{side}, {side}], [0, {side}]]}}\n"


# 1. Extent: a 191-byte course of a 10 km square asked for a 62 GB passability grid.


def test_a_10_km_square_is_refused_fast_naming_the_extent_limit(tmp_path):
    path = tmp_path / "huge.yml"
    path.write_text(square_corridor(10_000) + "obstacles: [{shape: cylinder, position: [5000, 0], radius: 0.2}]\n" + START)
    assert path.stat().st_size < 200
    error = refused(path, "MAX_COURSE_SIDE = 200", field="corridor")
    assert "10,001.6 m x 10,001.6 m" in str(error)
    assert str(path) in str(error)


def test_a_course_just_inside_the_extent_limit_loads():
    side = MAX_COURSE_SIDE - 2.0 * (0.7 + 0.1) - 0.01  # the walls lie width / 2 + a wall thickness beyond the centre line
    course = course_from_dict(
        {
            "corridor": {"width": 1.4, "centerline": [[0, 0], [side, 0], [side, side], [0, side]]},
            "start": {"x": 4.0, "y": 0.0, "heading_deg": 0.0},
        }
    )
    x_min, y_min, x_max, y_max = course.bounds
    assert max(x_max - x_min, y_max - y_min) <= MAX_COURSE_SIDE


def test_walls_far_apart_are_refused_by_the_extent_of_the_whole_course():
    data = {
        "walls": [[[-1, -1], [9, -1], [9, 7], [-1, 7], [-1, -1]], [[500, 0], [501, 0]]],
        "start": {"x": 4.0, "y": 0.0, "heading_deg": 0.0},
    }
    refused(data, "MAX_COURSE_SIDE", field="<extent>")


def test_the_passability_grid_is_bounded_before_it_is_allocated():
    course = load_course("unseen_posts")
    begin = time.perf_counter()
    with pytest.raises(CourseError, match="MAX_GRID_CELLS") as error:
        robot_fits(course, 0.15, resolution=0.001)  # 18 m x 12 m at 1 mm: 220 million cells
    assert time.perf_counter() - begin < FAST
    assert error.value.field == "<extent>"
    assert course.source in str(error.value)


def test_the_largest_course_fits_the_passability_grid():
    cells = math.ceil((MAX_COURSE_SIDE + 2.0 * (0.15 + 2.0 * GRID_RESOLUTION)) / GRID_RESOLUTION) ** 2
    assert cells <= MAX_GRID_CELLS


# 2. Counts: 33 kB of centre-line points asked for 22.5 GiB, 16,000 obstacles ended in a MemoryError.


def test_33_kb_of_far_apart_centre_line_points_are_refused_fast(tmp_path):
    points = [[i % 2 * 5_000, i] for i in range(2_500)]
    path = tmp_path / "points.yml"
    path.write_text(f"corridor: {{width: 1.4, centerline: {json.dumps(points)}}}\n" + START)
    assert path.stat().st_size > 30_000
    refused(path, "MAX_CENTERLINE_POINTS = 2,000", field="corridor.centerline")


def test_too_many_centre_line_points_are_refused_before_they_are_read():
    points = [[math.cos(a), math.sin(a)] for a in np.linspace(0.0, 2.0 * math.pi, MAX_CENTERLINE_POINTS + 1)]
    data = {"corridor": {"width": 0.2, "centerline": points}, "start": {"x": 1.0, "y": 0.0, "heading_deg": 90.0}}
    refused(data, "MAX_CENTERLINE_POINTS", field="corridor.centerline")


def test_a_long_zigzag_inside_the_extent_is_refused_by_the_distance_bound():
    # 1,000 points within the extent limit, but 199 m apart: 4 million samples x 2,000 walls.
    points = [[i * 0.1, 199.0 * (i % 2)] for i in range(1_000)]
    data = {"corridor": {"width": 0.05, "centerline": points}, "start": {"x": 0.0, "y": 0.0, "heading_deg": 0.0}}
    refused(data, f"MAX_OVERLAP_CHECK_DISTANCES = {MAX_OVERLAP_CHECK_DISTANCES:,}", field="corridor.centerline")


def test_rounded_corners_may_not_multiply_the_wall_segments():
    # A star of 1,000 sharp corners: rounding each adds up to 24 vertices.
    n = 1_000
    angles = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    radii = np.where(np.arange(n) % 2 == 0, 90.0, 60.0)
    points = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)]).tolist()
    data = {
        "corridor": {"width": 0.4, "centerline": points, "corner_radius": 0.01},
        "start": {"x": 90.0, "y": 0.0, "heading_deg": 90.0},
    }
    refused(data, f"MAX_WALL_SEGMENTS = {MAX_WALL_SEGMENTS:,}", field="corridor.corner_radius")


def test_too_many_wall_points_are_refused():
    polyline = [[i * 0.01, 0.0] for i in range(MAX_WALL_POINTS + 1)]
    refused({"walls": [polyline], "start": {"x": 0, "y": 0, "heading_deg": 0}}, "MAX_WALL_POINTS", field="walls")


def obstacles(n: int) -> list[dict[str, object]]:
    # On the far side of the loop from the start, in the free space: each one valid on its own.
    return [{"shape": "cylinder", "position": [2.0 + i % 9 * 0.5, 6.2], "radius": 0.01} for i in range(n)]


def test_16000_obstacles_in_a_file_are_refused_fast(tmp_path):
    data = {
        "corridor": {"width": 1.4, "centerline": [[0, 0], [8, 0], [8, 6], [0, 6]], "corner_radius": 1.5},
        "obstacles": obstacles(16_000),
        "start": {"x": 4.0, "y": 0.0, "heading_deg": 0.0},
    }
    path = tmp_path / "obstacles.json"
    path.write_text(json.dumps(data, separators=(",", ":")))
    too_long = path.stat().st_size > MAX_COURSE_FILE_BYTES
    refused(path, "MAX_COURSE_FILE_BYTES" if too_long else "MAX_OBSTACLES", field="<file>" if too_long else "obstacles")


def test_16000_obstacles_in_memory_are_refused_fast_naming_the_limit():
    data = {
        "corridor": {"width": 1.4, "centerline": [[0, 0], [8, 0], [8, 6], [0, 6]], "corner_radius": 1.5},
        "obstacles": obstacles(16_000),
        "start": {"x": 4.0, "y": 0.0, "heading_deg": 0.0},
    }
    error = refused(data, f"16,000 obstacles; a course may have at most MAX_OBSTACLES = {MAX_OBSTACLES}", field="obstacles")
    assert "hostile.yml" in str(error)
    corridor = course_from_dict({key: value for key, value in data.items() if key != "obstacles"})
    begin = time.perf_counter()
    with pytest.raises(CourseError, match="MAX_OBSTACLES"):
        with_obstacles(corridor, obstacles(16_000))
    assert time.perf_counter() - begin < FAST


# 3. YAML: 200 kB of nested lists took 282 s before they were refused.


def test_200_kb_of_nested_lists_are_refused_in_under_a_second(tmp_path):
    path = tmp_path / "nested.yml"
    path.write_text("name: " + "[" * 100_000 + "]" * 100_000 + "\n")
    error = refused(path, f"MAX_YAML_DEPTH = {MAX_YAML_DEPTH}", field="<file>")
    assert "line 1" in str(error)


def test_deeply_nested_block_lists_are_refused_fast(tmp_path):
    path = tmp_path / "block.yml"
    path.write_text("name:\n" + "- " * 20_000 + "x\n")  # compact nested block sequences: - - - x
    refused(path, "MAX_YAML_DEPTH", field="<file>")


def test_too_many_yaml_values_are_refused_before_they_are_built(tmp_path):
    path = tmp_path / "values.yml"
    path.write_text("description: [" + "0," * (MAX_YAML_VALUES + 1) + "0]\n")
    assert path.stat().st_size <= MAX_COURSE_FILE_BYTES
    # Read at PyYAML's speed (about 60 kB/s) up to the bound: slower than FAST, bounded by MAX_COURSE_FILE_BYTES.
    refused(path, "MAX_YAML_VALUES", field="<file>", within=10.0)


@pytest.mark.parametrize(
    ("text", "exceeds"),
    [
        ("a: [[1, 2], [3, 4]]", False),
        ("a: '[[[[[[[[[[[[[[[[[['", False),  # inside a quoted scalar
        ('a: "\\"[[[[[[[[[[[[[[[[[[["', False),  # an escaped quote does not end the scalar
        ("a: 1 # [[[[[[[[[[[[[[[[[[[", False),  # a comment
        ("a: it's [[[[[[[[[[[[[[[[[", True),  # a plain scalar: counted, conservatively
        ("a: " + "[" * 17, True),
    ],
)
def test_the_flow_depth_pre_scan(text, exceeds):
    assert (flow_depth_exceeds(text) is not None) == exceeds


def test_aliases_are_still_refused(tmp_path):
    path = tmp_path / "alias.yml"
    path.write_text("a: &a [1, 2]\nb: *a\n" + square_corridor(8) + START)
    refused(path, "aliases", field="<file>")


# 4. Numbers: exponents without a dot are numbers, never strings compared with numbers; non-finite values are refused.


@pytest.mark.parametrize("field", ["wall_thickness", "corridor.width", "start.x"])
@pytest.mark.parametrize(("written", "message"), [("1e300", "out of range"), (".inf", "finite"), (".nan", "finite")])
def test_huge_and_non_finite_numbers_are_refused_naming_the_field(tmp_path, field, written, message):
    values = {"wall_thickness": "0.1", "corridor.width": "1.4", "start.x": "4.0"} | {field: written}
    path = tmp_path / "numbers.yml"
    path.write_text(
        f"wall_thickness: {values['wall_thickness']}\n"
        f"corridor: {{width: {values['corridor.width']}, centerline: [[0, 0], [8, 0], [8, 6], [0, 6]]}}\n"
        f"start: {{x: {values['start.x']}, y: 0.0, heading_deg: 0.0}}\n"
    )
    refused(path, message, field=field)


def test_a_quoted_number_is_refused_as_a_string_naming_the_field(tmp_path):
    path = tmp_path / "quoted.yml"
    path.write_text(square_corridor(8) + "start: {x: '1e300', y: 0.0, heading_deg: 0.0}\n")
    refused(path, "must be a number, got '1e300'", field="start.x")


# 5. Encoding.


def test_a_file_that_is_not_utf_8_names_the_file(tmp_path):
    path = tmp_path / "latin1.yml"
    path.write_bytes("name: K\xf6rper\n".encode("latin-1") + (square_corridor(8) + START).encode())
    error = refused(path, "not a UTF-8 text file", field="<file>")
    assert str(path) in str(error)


# 6. What ships still loads, well inside every bound.


@pytest.mark.parametrize("name", shipped_courses())
def test_every_shipped_course_loads_well_inside_the_bounds(name):
    course = load_course(name)
    course.check_robot_fits(0.15)
    x_min, y_min, x_max, y_max = course.bounds
    assert max(x_max - x_min, y_max - y_min) < MAX_COURSE_SIDE / 5
    assert len(course.walls) < MAX_WALL_SEGMENTS / 10
    assert len(course.obstacles) < MAX_OBSTACLES / 10
    if course.corridor is not None:
        assert len(course.corridor.centerline) < MAX_CENTERLINE_POINTS / 10


def test_procedural_layouts_still_generate_well_inside_the_bounds():
    generator = CourseGenerator()
    for seed in range(0, 200, 10):
        course = generator.generate(seed)
        x_min, y_min, x_max, y_max = course.bounds
        assert max(x_max - x_min, y_max - y_min) < MAX_COURSE_SIDE / 5
        assert len(course.walls) < MAX_WALL_SEGMENTS / 10


def test_every_limit_is_a_documented_module_constant():
    for name in (
        "MAX_COURSE_FILE_BYTES",
        "MAX_COURSE_SIDE",
        "MAX_CENTERLINE_POINTS",
        "MAX_WALL_POINTS",
        "MAX_WALL_SEGMENTS",
        "MAX_OBSTACLES",
        "MAX_OVERLAP_CHECK_DISTANCES",
    ):
        assert f":data:`{name}`" in course_module.__doc__
