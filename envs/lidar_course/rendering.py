"""Top-down ``rgb_array`` pictures of a lidar course, drawn with Pillow (no window, no GPU)."""

from __future__ import annotations

import numpy as np

from sb3_adc.extras import requires_extra

with requires_extra("envs", "rendering the lidar obstacle course"):
    from PIL import Image, ImageDraw

from sb3_adc_envs.lidar_course.course import Course

_BACKGROUND = (255, 255, 255)
_WALL = (60, 60, 60)
_OBSTACLE = (120, 120, 120)
_PATH = (31, 119, 180)
_RAY = (255, 150, 150)
_RAY_HIT = (214, 39, 40)
_ROBOT = (255, 127, 14)
_ROBOT_CRASHED = (214, 39, 40)
_HEADING = (0, 0, 0)


class TopDownRenderer:
    """
    Draws the course's walls and obstacles, the robot, its lidar rays and the path driven so far, seen from above.

    The walls are drawn once; each frame copies that background and draws the moving parts on it.

    :param course: The course
    :param max_side_px: Size of the picture's longer side [pixels]
    :param margin: Free space around the walls [m]
    """

    def __init__(self, course: Course, max_side_px: int = 480, margin: float = 0.5):
        x_min, y_min, x_max, y_max = course.bounds
        self._x_min = x_min - margin
        self._y_max = y_max + margin
        width_m = x_max - x_min + 2.0 * margin
        height_m = y_max - y_min + 2.0 * margin
        self.pixels_per_metre = max_side_px / max(width_m, height_m)
        self.size = (round(width_m * self.pixels_per_metre), round(height_m * self.pixels_per_metre))
        self._background = Image.new("RGB", self.size, _BACKGROUND)
        draw = ImageDraw.Draw(self._background)
        wall_px = max(2, round(course.wall_thickness * self.pixels_per_metre))
        for x0, y0, x1, y1 in course.walls:
            draw.line([self.to_pixels(x0, y0), self.to_pixels(x1, y1)], fill=_WALL, width=wall_px)
        for obstacle in course.obstacles:
            draw.polygon([self.to_pixels(x, y) for x, y in obstacle.footprint()], fill=_OBSTACLE, outline=_WALL)

    def to_pixels(self, x: float, y: float) -> tuple[float, float]:
        """Picture coordinates (column, row) of a point of the course (y points up in the picture)."""
        return (x - self._x_min) * self.pixels_per_metre, (self._y_max - y) * self.pixels_per_metre

    def render(
        self,
        path: np.ndarray,
        pose: tuple[float, float, float],
        robot_radius: float,
        ray_ends: np.ndarray,
        ray_hit: np.ndarray,
        crashed: bool,
    ) -> np.ndarray:
        """
        One frame.

        :param path: ``(n, 2)`` positions driven so far [m]
        :param pose: ``(x, y, heading)`` of the robot [m, m, rad]
        :param robot_radius: Radius of the robot [m]
        :param ray_ends: ``(n_rays, 2)`` end points of the rays (where they hit, or their full length) [m]
        :param ray_hit: ``(n_rays,)`` whether each ray hit a wall
        :param crashed: Whether the robot touches a wall (drawn red)
        :return: ``(height, width, 3)`` ``uint8`` picture
        """
        frame = self._background.copy()
        draw = ImageDraw.Draw(frame)
        x, y, heading = pose
        centre = self.to_pixels(x, y)
        for (end_x, end_y), hit in zip(ray_ends, ray_hit, strict=True):
            end = self.to_pixels(end_x, end_y)
            draw.line([centre, end], fill=_RAY, width=1)
            if hit:
                draw.ellipse([end[0] - 2, end[1] - 2, end[0] + 2, end[1] + 2], fill=_RAY_HIT)
        if len(path) > 1:
            draw.line([self.to_pixels(px, py) for px, py in path], fill=_PATH, width=2)
        radius_px = max(3.0, robot_radius * self.pixels_per_metre)
        draw.ellipse(
            [centre[0] - radius_px, centre[1] - radius_px, centre[0] + radius_px, centre[1] + radius_px],
            fill=_ROBOT_CRASHED if crashed else _ROBOT,
            outline=_HEADING,
        )
        nose = self.to_pixels(x + robot_radius * np.cos(heading), y + robot_radius * np.sin(heading))
        draw.line([centre, nose], fill=_HEADING, width=2)
        return np.asarray(frame, dtype=np.uint8)
