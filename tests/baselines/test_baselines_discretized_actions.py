"""DiscretizedActions: a Box action space as evenly spaced discrete actions."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from sb3_adc_envs.wrappers import DiscretizedActions


class BoxActionEnv(gym.Env):
    """Records the last action it was given."""

    observation_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, low, high):
        self.action_space = spaces.Box(np.asarray(low, np.float32), np.asarray(high, np.float32))
        self.last_action = None

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.last_action = action
        return np.zeros(1, np.float32), 0.0, False, False, {}


def test_pendulum_edges_and_spacing():
    env = DiscretizedActions(gym.make("Pendulum-v1"), 25)
    assert env.action_space == spaces.Discrete(25)
    np.testing.assert_array_equal(env.action(0), [-2.0])
    np.testing.assert_array_equal(env.action(24), [2.0])
    np.testing.assert_allclose(env.action(12), [0.0], atol=1e-7)
    values = np.array([env.action(i)[0] for i in range(25)])
    np.testing.assert_allclose(np.diff(values), 4.0 / 24, rtol=1e-5)
    assert env.action(3).dtype == np.float32


def test_the_wrapped_env_receives_the_continuous_action():
    inner = BoxActionEnv([-0.5], [1.5])
    env = DiscretizedActions(inner, 5)
    env.reset(seed=0)
    env.step(np.int64(4))
    np.testing.assert_array_equal(inner.last_action, [1.5])
    env.step(1)
    np.testing.assert_allclose(inner.last_action, [0.0])


def test_multi_dimensional_grid():
    env = DiscretizedActions(BoxActionEnv([-1.0, 0.0], [1.0, 10.0]), 3)
    assert env.action_space == spaces.Discrete(9)
    np.testing.assert_array_equal(env.action(0), [-1.0, 0.0])
    np.testing.assert_array_equal(env.action(8), [1.0, 10.0])
    # The last dimension varies fastest.
    np.testing.assert_array_equal(env.action(1), [-1.0, 5.0])
    np.testing.assert_array_equal(env.action(3), [0.0, 0.0])
    grid = {tuple(env.action(i)) for i in range(9)}
    assert len(grid) == 9


@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (lambda: DiscretizedActions(gym.make("CartPole-v1"), 5), TypeError, "needs a Box action space"),
        (lambda: DiscretizedActions(BoxActionEnv([-np.inf], [1.0]), 5), ValueError, "finite action bounds"),
        (lambda: DiscretizedActions(gym.make("Pendulum-v1"), 1), ValueError, "`n_actions` must be an integer >= 2"),
        (lambda: DiscretizedActions(gym.make("Pendulum-v1"), 2.5), ValueError, "`n_actions` must be an integer >= 2"),
        (lambda: DiscretizedActions(BoxActionEnv([0.0] * 5, [1.0] * 5), 25), ValueError, "exceeds 1000000 actions"),
    ],
)
def test_invalid_arguments(make, error, message):
    with pytest.raises(error, match=message):
        make()


def test_out_of_range_action():
    env = DiscretizedActions(gym.make("Pendulum-v1"), 25)
    with pytest.raises(ValueError, match=r"action 25 is outside \[0, 25\)"):
        env.action(25)
