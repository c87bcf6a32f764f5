"""One pybullet client per environment, released on close() and on garbage collection."""

from __future__ import annotations

import gc

import numpy as np
import pybullet

from sb3_adc_envs.lidar_course import LidarObstacleCourseEnv


def test_each_environment_has_its_own_physics_client():
    # Two environments stepped in turn read exactly what one stepped alone reads: no shared world.
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, size=(40, 1)).astype(np.float32)
    alone = LidarObstacleCourseEnv(course="unseen_wide")
    expected = [alone.reset()[0]] + [alone.step(action)[0] for action in actions]
    first = LidarObstacleCourseEnv(course="training")
    second = LidarObstacleCourseEnv(course="unseen_wide")
    assert len({alone._simulation.client_id, first._simulation.client_id, second._simulation.client_id}) == 3
    first.reset()
    observed = [second.reset()[0]]
    for action in actions:
        first.step(-action)
        observed.append(second.step(action)[0])
    np.testing.assert_array_equal(np.array(observed), np.array(expected))
    for env in (alone, first, second):
        env.close()


def test_close_disconnects_and_is_idempotent():
    env = LidarObstacleCourseEnv(course="training")
    client = env._simulation.client_id
    assert pybullet.isConnected(client)
    env.close()
    assert not pybullet.isConnected(client)
    env.close()  # a second close is harmless
    assert env._simulation.client_id is None


def test_garbage_collection_disconnects():
    env = LidarObstacleCourseEnv(course="training")
    client = env._simulation.client_id
    del env
    gc.collect()
    assert not pybullet.isConnected(client)


def test_many_environments_do_not_leak_clients():
    clients = []
    for _ in range(20):
        env = LidarObstacleCourseEnv(course="unseen_arena")
        env.reset()
        clients.append(env._simulation.client_id)
        env.close()
    assert not any(pybullet.isConnected(client) for client in clients)
