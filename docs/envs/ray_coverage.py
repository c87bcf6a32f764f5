"""How often the lidar misses a nearby obstacle, for several numbers of rays (the evidence for ``-v1``'s default)
and of rays per reading (``rays_per_reading``: each reading the nearest hit of several rays over its sector).

On procedural layouts (layout seeds outside both the training and the held-out range), the robot is placed at
poses along the corridor (every 0.5 m of the centre line, a random offset across it and a heading within 30
degrees of the centre line's); for every obstacle whose surface lies within ``NEAR`` of the robot's centre, it
records whether at least one reading shows that obstacle (its ray, or its nearest ray's hit, is on the obstacle).
The rays and the poses are those of the environment (:class:`~sb3_adc_envs.lidar_course.env.LidarObstacleCourseEnv`,
3 m rays over 360 degrees).

Writes ``docs/envs/ray_coverage.csv``; about a minute on one core::

    python docs/envs/ray_coverage.py
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np

from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv

OUT = Path(__file__).resolve().parent / "ray_coverage.csv"
#: Layout seeds of the experiment: neither training nor held-out evaluation layouts.
LAYOUT_SEEDS = range(5_000_000, 5_000_040)
#: The lidars compared: (readings, rays per reading).
LIDARS = ((8, 1), (12, 1), (16, 1), (24, 1), (32, 1), (24, 2), (24, 4), (24, 8))
#: An obstacle counts when its surface is this close to the robot's centre [m].
NEAR = 1.5
#: An obstacle counts as thin when it is at most this wide in every direction (a post, a small box) [m].
THIN = 0.2


def main() -> None:
    rng = np.random.default_rng(0)
    envs = {(n, k): LidarObstacleCourseEnv(course="procedural", n_rays=n, rays_per_reading=k) for n, k in LIDARS}
    missed = {(lidar, kind): 0 for lidar in LIDARS for kind in ("thin", "all")}
    seen_total = {"thin": 0, "all": 0}
    readings = {(n, k): np.ones(n, dtype=np.float32) for n, k in LIDARS}
    for layout_seed in LAYOUT_SEEDS:
        for env in envs.values():
            env.reset(options={"layout_seed": layout_seed})
        course = envs[LIDARS[0]].course
        assert course.corridor is not None
        centre = course.corridor.centerline
        closed = np.vstack([centre, centre[:1]])
        for (x0, y0), (x1, y1) in itertools.pairwise(closed):
            length = math.hypot(x1 - x0, y1 - y0)
            heading = math.atan2(y1 - y0, x1 - x0)
            for fraction in np.arange(0.0, length, 0.5) / length:
                across = rng.uniform(-0.35, 0.35) * course.corridor.width
                x = x0 + fraction * (x1 - x0) - math.sin(heading) * across
                y = y0 + fraction * (y1 - y0) + math.cos(heading) * across
                pose_heading = heading + math.radians(rng.uniform(-30.0, 30.0))
                if course.clearance(x, y) <= 0.15:
                    continue  # the robot would touch something here
                near = [i for i, obstacle in enumerate(course.obstacles) if obstacle.distance(x, y) <= NEAR]
                if not near:
                    continue
                hits = {}
                for lidar, env in envs.items():
                    env.simulation.move_robot(x, y, pose_heading, readings[lidar])
                    hits[lidar] = set(env.simulation.ray_bodies)
                for i in near:
                    obstacle = course.obstacles[i]
                    kinds = ["all"] + (["thin"] if max(obstacle.length, obstacle.width) <= THIN else [])
                    for kind in kinds:
                        seen_total[kind] += 1
                        for lidar, env in envs.items():
                            if env.simulation.obstacle_ids[i] not in hits[lidar]:
                                missed[lidar, kind] += 1
    for env in envs.values():
        env.close()
    lines = [
        "rays (readings),rays per reading,rays cast,angle between rays cast (deg),"
        "missed obstacles within 1.5 m (%),missed thin obstacles within 1.5 m (%)"
    ]
    for n, k in LIDARS:
        all_rate = 100.0 * missed[(n, k), "all"] / seen_total["all"]
        thin_rate = 100.0 * missed[(n, k), "thin"] / seen_total["thin"]
        lines.append(f"{n},{k},{n * k},{360 / (n * k):g},{all_rate:.1f},{thin_rate:.1f}")
    OUT.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"({seen_total['all']} obstacle sightings, {seen_total['thin']} of thin obstacles; wrote {OUT})")


if __name__ == "__main__":
    main()
