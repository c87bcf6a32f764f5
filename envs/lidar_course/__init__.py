"""The lidar obstacle course: a pybullet robot with a planar lidar in a walled course loaded from a file."""

from sb3_adc_envs.lidar_course.course import Course, CourseError, StartPose, shipped_courses
from sb3_adc_envs.lidar_course.course_parsing import load_course
from sb3_adc_envs.lidar_course.env import LidarObstacleCourseEnv
from sb3_adc_envs.lidar_course.noisy import make_noisy_lidar_course

__all__ = [
    "Course",
    "CourseError",
    "LidarObstacleCourseEnv",
    "StartPose",
    "load_course",
    "make_noisy_lidar_course",
    "shipped_courses",
]
