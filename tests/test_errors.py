"""Bad input gets a clear error that names the parameter and the accepted values."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3 import DDPG

from sb3_adc import ADC, ADCPolicy

TINY = dict(net_arch=[8], n_intervals=4)


class ReplaceActionSpace(gym.ActionWrapper):
    """Give Pendulum another action space, to check what ADC accepts."""

    def __init__(self, env, action_space):
        super().__init__(env)
        self.action_space = action_space

    def action(self, action):
        return action


def pendulum_with(action_space):
    return ReplaceActionSpace(gym.make("Pendulum-v1"), action_space)


@pytest.mark.parametrize("action_space", [spaces.Discrete(3), spaces.MultiDiscrete([3, 2]), spaces.MultiBinary(2)])
def test_discrete_action_spaces_are_rejected(action_space):
    with pytest.raises(TypeError, match=r"`action_space` must be a continuous gymnasium\.spaces\.Box") as error:
        ADC("MlpPolicy", pendulum_with(action_space))
    assert "DQN" in str(error.value)


def test_discrete_env_id_is_rejected():
    with pytest.raises(TypeError, match=r"action_space.*Discrete"):
        ADC("MlpPolicy", "CartPole-v1")


@pytest.mark.parametrize(
    ("low", "high"),
    [(-np.inf, 1.0), (-1.0, np.inf), (np.array([-1.0, -np.inf]), np.array([1.0, 1.0]))],
)
def test_unbounded_action_ranges_are_rejected(low, high):
    shape = np.shape(low) or (1,)
    with pytest.raises(ValueError, match="`action_space` must have finite bounds"):
        ADC("MlpPolicy", pendulum_with(spaces.Box(low, high, shape, np.float32)))


def test_non_finite_bounds_rejected_by_the_policy_too():
    observation_space = spaces.Box(-1, 1, (3,), np.float32)
    with pytest.raises(ValueError, match="finite bounds"):
        ADCPolicy(observation_space, spaces.Box(-np.inf, np.inf, (1,), np.float32), lambda _: 1e-3)


@pytest.mark.parametrize("n_intervals", [1, 0, -5, 3.0])
def test_too_few_intervals_are_rejected(n_intervals):
    with pytest.raises(ValueError, match=r"`n_intervals` must be an integer >= 2"):
        ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(n_intervals=n_intervals))


def test_unknown_aggregation_is_rejected():
    with pytest.raises(ValueError, match=r"`aggregation` must be one of \('mean', 'max'\), got 'avg'"):
        ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(aggregation="avg"))


def test_unknown_interpolation_is_rejected():
    with pytest.raises(ValueError, match=r"`advantage_interpolation` must be one of \('none', 'linear'\)"):
        ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(advantage_interpolation="spline"))


def test_unknown_policy_alias_is_rejected():
    with pytest.raises(ValueError, match="Policy LstmPolicy unknown"):
        ADC("LstmPolicy", "Pendulum-v1")


def test_foreign_policy_class_is_rejected():
    from stable_baselines3.td3.policies import TD3Policy

    with pytest.raises(TypeError, match=r"`policy` must be one of .* or a subclass of ADCPolicy"):
        ADC(TD3Policy, "Pendulum-v1")


@pytest.fixture
def saved_model(tmp_path):
    path = tmp_path / "adc.zip"
    ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, seed=0).save(path)
    return path


def test_loading_with_a_mismatched_action_space_names_the_file(saved_model):
    env = pendulum_with(spaces.Box(-1.0, 1.0, (2,), np.float32))
    with pytest.raises(ValueError, match=r"Cannot load the ADC model .*adc\.zip.*Action spaces do not match"):
        ADC.load(saved_model, env=env)


def test_loading_with_a_discrete_env_is_rejected(saved_model):
    with pytest.raises(TypeError, match="action_space"):
        ADC.load(saved_model, env=gym.make("CartPole-v1"))


def test_loading_parameters_with_other_n_intervals_is_rejected(saved_model):
    other = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(TINY, n_intervals=6))
    with pytest.raises(ValueError, match=r"`n_intervals` mismatch: the saved critic has n_intervals=4.*n_intervals=6"):
        other.set_parameters(str(saved_model))
    with pytest.raises(ValueError, match="n_intervals"):
        other.set_parameters(ADC.load(saved_model).get_parameters())


def test_loading_with_overridden_n_intervals_is_rejected(saved_model):
    with pytest.raises(ValueError, match="n_intervals"):
        ADC.load(saved_model, custom_objects={"policy_kwargs": dict(TINY, n_intervals=9)})


def test_loading_a_ddpg_model_is_rejected(tmp_path):
    path = tmp_path / "ddpg.zip"
    DDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8])).save(path)
    with pytest.raises(TypeError, match=r"subclass of ADCPolicy.*saved by another algorithm"):
        ADC.load(path)


def test_ddpg_parameters_are_rejected(tmp_path):
    path = tmp_path / "ddpg.zip"
    DDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8])).save(path)
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY)
    with pytest.raises(ValueError, match="not saved by an ADC model"):
        model.set_parameters(str(path))


def test_corrupt_model_file_is_rejected(tmp_path):
    path = tmp_path / "corrupt.zip"
    path.write_bytes(b"this is not a zip archive")
    with pytest.raises(ValueError, match=r"Cannot load the ADC model .*corrupt\.zip.*wasn't a zip-file"):
        ADC.load(path)


def test_truncated_model_file_is_rejected(saved_model, tmp_path):
    truncated = tmp_path / "truncated.zip"
    truncated.write_bytes(saved_model.read_bytes()[:-200])
    with pytest.raises(ValueError, match=r"truncated\.zip is not a readable ADC model file"):
        ADC.load(truncated)


def test_missing_model_file_is_reported(tmp_path):
    with pytest.raises(FileNotFoundError):
        ADC.load(tmp_path / "missing.zip")
