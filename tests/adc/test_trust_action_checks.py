"""Action noise of the wrong length, and the advice given for an unbounded action space."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3.common.noise import NormalActionNoise, VectorizedActionNoise

from sb3_adc import ADC
from sb3_adc.common.noise import EpsilonGaussianNoise, check_action_noise
from sb3_adc.common.spaces import ActionBoundsError, check_action_space

BOX_3 = spaces.Box(-1.0, 1.0, (3,), np.float32)


def epsilon_noise(n: int) -> EpsilonGaussianNoise:
    return EpsilonGaussianNoise(mean=np.zeros(n), sigma=np.full(n, 0.1), decay_steps=100)


def test_noise_of_one_value_on_three_action_dimensions_is_refused():
    with pytest.raises(ValueError, match=r"`mean` and `sigma` have shape \(1,\).*\(3,\) \(3 action dimensions\)"):
        check_action_noise(epsilon_noise(1), BOX_3)


@pytest.mark.parametrize(
    "noise",
    [
        epsilon_noise(2),
        EpsilonGaussianNoise(mean=0.0, sigma=0.1, decay_steps=10),
        NormalActionNoise(mean=np.zeros(1), sigma=np.full(1, 0.1)),
        VectorizedActionNoise(epsilon_noise(1), n_envs=2),
    ],
)
def test_every_mismatched_noise_is_refused(noise):
    with pytest.raises(ValueError, match="one value per dimension"):
        check_action_noise(noise, BOX_3)


@pytest.mark.parametrize(
    ("noise", "space"),
    [
        (None, BOX_3),
        (epsilon_noise(3), BOX_3),
        (NormalActionNoise(mean=np.zeros(3), sigma=np.full(3, 0.1)), BOX_3),
        (VectorizedActionNoise(epsilon_noise(3), n_envs=2), BOX_3),
        (EpsilonGaussianNoise(mean=0.0, sigma=0.1, decay_steps=10), spaces.Box(-1.0, 1.0, (1,), np.float32)),
        (epsilon_noise(1), spaces.Box(-1.0, 1.0, (1,), np.float32)),
    ],
)
def test_matching_noise_passes(noise, space):
    check_action_noise(noise, space)
    if noise is not None and not isinstance(noise, VectorizedActionNoise):
        assert np.broadcast_shapes(np.shape(noise()), space.shape) == space.shape


class ThreeActions(gym.Env):
    observation_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
    action_space = BOX_3

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(2, np.float32), {}

    def step(self, action):
        return np.zeros(2, np.float32), 0.0, False, False, {}


def test_adc_refuses_noise_of_the_wrong_length():
    with pytest.raises(ValueError, match="`mean` and `sigma` have shape"):
        ADC("MlpPolicy", ThreeActions(), action_noise=epsilon_noise(1), device="cpu")


def test_unbounded_space_advice_is_one_that_works():
    unbounded = spaces.Box(-np.inf, np.inf, (2,), np.float32)
    with pytest.raises(ActionBoundsError) as caught:
        check_action_space(unbounded)
    message = str(caught.value)
    assert "true, finite limits of the actuator" in message
    assert "gymnasium.ActionWrapper" in message
    assert "e.g. with gymnasium.wrappers.RescaleAction or ClipAction" not in message
    # The advice works: a wrapper that declares the actuator's limits gives a space ADC accepts ...

    class Limits(gym.ActionWrapper):
        def __init__(self, env):
            super().__init__(env)
            self.action_space = spaces.Box(-2.0, 2.0, (2,), np.float32)

        def action(self, action):
            return action

    class Unbounded(ThreeActions):
        action_space = unbounded

    check_action_space(Limits(Unbounded()).action_space)
    # ... where the wrappers the old message advised do not.
    assert not np.all(np.isfinite(gym.wrappers.ClipAction(Unbounded()).action_space.high))
    with pytest.raises(ValueError):  # noqa: PT011 - gymnasium's own message
        gym.wrappers.RescaleAction(Unbounded(), -1.0, 1.0)
