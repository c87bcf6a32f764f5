"""Shared helpers of the environment tests: small courses built in memory."""

from __future__ import annotations

from typing import Any

import pytest

from sb3_adc_envs.lidar_course import Course
from sb3_adc_envs.lidar_course.course_parsing import course_from_dict

#: Inner faces of the walls of :func:`box_course` (walls centred on 0 and `size`, 0.1 m thick).
WALL_THICKNESS = 0.1


def box_course(size: float = 10.0, start: tuple[float, float, float] = (5.0, 5.0, 0.0)) -> Course:
    """
    A square arena whose walls are centred on x = 0, x = size, y = 0 and y = size (0.1 m thick),
    so that the free space is ``[0.05, size - 0.05]`` on both axes.

    :param size: Side of the square [m]
    :param start: ``(x, y, heading_deg)`` of the start pose
    """
    data: dict[str, Any] = {
        "name": "box",
        "wall_thickness": WALL_THICKNESS,
        "walls": [[[0.0, 0.0], [size, 0.0], [size, size], [0.0, size], [0.0, 0.0]]],
        "start": {"x": start[0], "y": start[1], "heading_deg": start[2]},
    }
    return course_from_dict(data, source="box.yml")


@pytest.fixture(name="box_course")
def box_course_factory():
    """The :func:`box_course` factory: ``box_course(size, (x, y, heading_deg))``."""
    return box_course
