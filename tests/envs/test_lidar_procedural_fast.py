"""The fast paths of procedural layouts give what the plain ones give, bit for bit.

:func:`~sb3_adc_envs.lidar_course.procedural.corridor_course` builds a generator's draw as
:func:`~sb3_adc_envs.lidar_course.course_parsing.course_from_dict` does (refusing the same draws), and
:func:`~sb3_adc_envs.lidar_course.geometry.nearest_segment_distances` measures only the pairs within reach, with
the numbers of :func:`~sb3_adc_envs.lidar_course.geometry.point_segment_distances`.
"""

from __future__ import annotations

import contextlib
from typing import Any

import numpy as np
import pytest

from sb3_adc_envs.lidar_course import geometry, procedural
from sb3_adc_envs.lidar_course.course import Course, CourseError
from sb3_adc_envs.lidar_course.course_parsing import course_from_dict
from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS, TRAIN_LAYOUT_SEEDS, VALIDATION_LAYOUT_SEEDS
from sb3_adc_envs.lidar_course.procedural import CourseGenerator

#: Generators: the shipped one, and ones whose draws overlap themselves or fail their corners' rounding often.
GENERATORS = {
    "shipped": CourseGenerator(),
    "tight": CourseGenerator(n_corners=(7, 12), loop_radius=(2.0, 4.0), width=(1.2, 2.4), corner_radius=(0.6, 1.2)),
    "wide": CourseGenerator(n_corners=(3, 5), loop_radius=(3.0, 12.0), width=(1.0, 3.0), corner_radius=(1.0, 2.5)),
}


def assert_same_course(fast: Course, plain: Course) -> None:
    """Every field equal, arrays bit for bit."""
    assert fast.name == plain.name
    assert fast.source == plain.source
    assert fast.description == plain.description
    assert fast.wall_thickness == plain.wall_thickness
    assert fast.start == plain.start
    assert fast.obstacles == plain.obstacles
    np.testing.assert_array_equal(fast.walls, plain.walls)
    assert fast.walls.dtype == plain.walls.dtype
    assert fast.walls.shape == plain.walls.shape
    assert fast.corridor is not None
    assert plain.corridor is not None
    assert fast.corridor.width == plain.corridor.width
    np.testing.assert_array_equal(fast.corridor.centerline, plain.corridor.centerline)


@pytest.mark.parametrize("name", list(GENERATORS))
def test_corridor_course_builds_and_refuses_what_course_from_dict_does(monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    outcomes = {"built": 0, "refused": 0}
    fast_corridor_course = procedural.corridor_course

    def both(data: dict[str, Any], source: str) -> Course:
        try:
            plain = course_from_dict(data, source=source)
        except CourseError:
            with pytest.raises(CourseError):
                fast_corridor_course(data, source)
            outcomes["refused"] += 1
            raise
        fast = fast_corridor_course(data, source)
        assert_same_course(fast, plain)
        outcomes["built"] += 1
        return fast

    monkeypatch.setattr(procedural, "corridor_course", both)
    generator = GENERATORS[name]
    splits = (TRAIN_LAYOUT_SEEDS, TEST_LAYOUT_SEEDS, VALIDATION_LAYOUT_SEEDS)
    seeds = [*range(120), *(start + k for start, _ in splits for k in range(40))]
    for layout_seed in seeds:
        with contextlib.suppress(RuntimeError):  # no valid corridor in the draws allowed: the same with both
            generator.generate(layout_seed)
    assert outcomes["built"] >= len(set(seeds)) // 2
    assert outcomes["refused"] > 0, outcomes


def test_generated_layouts_are_those_of_course_from_dict() -> None:
    # The whole layout, obstacles included, against a generator built on course_from_dict.
    generator = CourseGenerator()
    for layout_seed in (0, 1, 17, 123_456, 1_000_003, 2_000_042):
        fast = generator.generate(layout_seed)
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(procedural, "corridor_course", lambda data, source: course_from_dict(data, source=source))
            plain = generator.generate(layout_seed)
        assert_same_course(fast, plain)


@pytest.mark.parametrize("seed", range(6))
def test_nearest_segment_distances_are_the_brute_force_minimum(seed: int) -> None:
    rng = np.random.default_rng(seed)
    points = rng.uniform(-5.0, 5.0, (300, 2))
    segments = np.hstack([rng.uniform(-5.0, 5.0, (80, 2)), np.zeros((80, 2))])
    # Short and long segments, and a few of zero length.
    segments[:, 2:] = segments[:, :2] + rng.normal(0.0, [[0.3], [3.0]][seed % 2], (80, 2))
    segments[:5, 2:] = segments[:5, :2]
    brute = geometry.point_segment_distances(points, segments).min(axis=1)
    for reach in (0.05, 0.4, 1.3, 20.0):
        nearest = geometry.nearest_segment_distances(points, segments, reach)
        within = brute <= reach
        np.testing.assert_array_equal(nearest[within], brute[within])
        assert np.all(nearest[~within] > reach)


def test_nearest_segment_distances_along_corridors() -> None:
    # The overlap check's inputs: centre-line samples against the corridor's walls.
    generator = CourseGenerator()
    for layout_seed in range(20):
        course = generator.generate(layout_seed)
        assert course.corridor is not None
        samples = geometry.sample_polyline(course.corridor.centerline, 0.05, closed=True)
        brute = geometry.point_segment_distances(samples, course.walls).min(axis=1)
        reach = course.corridor.width / 2.0 + course.wall_thickness / 2.0 + 1e-6
        nearest = geometry.nearest_segment_distances(samples, course.walls, reach)
        within = brute <= reach
        assert within.mean() > 0.5  # each sample's own walls lie at about that distance
        np.testing.assert_array_equal(nearest[within], brute[within])
        assert np.all(nearest[~within] > reach)
