"""``sb3_adc/HighwayObstacle-v0`` and ``-v1``: obstacle avoidance with one continuous steering action, built on highway-env."""

from sb3_adc_envs.highway_obstacle.env import PAPER_STEERING_RANGE, HighwayObstacleEnv, HighwayObstacleV1Env
from sb3_adc_envs.highway_obstacle.observation import RoadEdgeLidarObservation

__all__ = ["PAPER_STEERING_RANGE", "HighwayObstacleEnv", "HighwayObstacleV1Env", "RoadEdgeLidarObservation"]
