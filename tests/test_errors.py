"""Bad input gets a clear error that names the parameter and the accepted values."""

import errno

import gymnasium as gym
import numpy as np
import pytest
import torch as th
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


@pytest.mark.parametrize(
    ("action_space", "sb3_rejects_it"),
    [
        (spaces.Discrete(3), True),
        (spaces.Box(-np.inf, np.inf, (1,), np.float32), True),
        (spaces.Box(1.0, 1.0, (1,), np.float32), False),  # an empty range: SB3 does not check it
    ],
)
def test_unsupported_action_spaces_are_assertion_errors_as_in_sb3(action_space, sb3_rejects_it):
    # SB3 rejects unsupported spaces with `assert` (supported_action_spaces, finite bounds): code written against
    # SB3 catches AssertionError.
    from stable_baselines3 import TD3

    env = pendulum_with(action_space)
    with pytest.raises(AssertionError, match="`action_space` must"):
        ADC("MlpPolicy", env)
    if sb3_rejects_it:
        with pytest.raises(AssertionError):
            TD3("MlpPolicy", env)


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
    with pytest.raises(TypeError, match=r"adc\.zip for this env: `action_space` must be a continuous") as error:
        ADC.load(saved_model, env=gym.make("CartPole-v1"))
    # SB3's TD3.load raises ValueError (spaces do not match); ADC's constructor an AssertionError, as SB3's.
    assert isinstance(error.value, ValueError)
    assert isinstance(error.value, AssertionError)


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


def test_missing_model_file_is_reported_under_the_name_given(tmp_path):
    # SB3 retries "x.zip" as "x.zip.zip" and names that one.
    with pytest.raises(FileNotFoundError, match=r"No ADC model file at .*missing\.zip$") as error:
        ADC.load(tmp_path / "missing.zip")
    assert "missing.zip.zip" not in str(error.value)
    assert error.value.errno == errno.ENOENT
    with pytest.raises(FileNotFoundError, match=r"No ADC model file at .*missing \(nor .*missing\.zip\)"):
        ADC.load(str(tmp_path / "missing"))
    with pytest.raises(FileNotFoundError, match=r"missing\.zip$"):
        ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY).set_parameters(str(tmp_path / "missing.zip"))


def damaged_copies(saved_model, tmp_path):
    """A model file cut short, one without its parameters, one without its data: (path, error SB3's TD3 raises)."""
    import zipfile

    from stable_baselines3 import TD3

    cut = tmp_path / "cut.zip"
    cut.write_bytes(saved_model.read_bytes()[:-200])
    copies = {"cut": cut}
    for dropped in ("policy.pth", "data"):
        path = tmp_path / f"without-{dropped}.zip"
        with zipfile.ZipFile(saved_model) as source, zipfile.ZipFile(path, "w") as target:
            for name in source.namelist():
                if name != dropped:
                    target.writestr(name, source.read(name))
        copies[f"without {dropped}"] = path
    expected = {}
    for name, path in copies.items():
        try:
            TD3.load(path)
        except Exception as sb3_error:  # whatever SB3 raises is the type to match
            expected[name] = (path, type(sb3_error))
        else:
            pytest.fail(f"TD3.load accepted the damaged file {path}")
    return expected


def test_load_errors_name_the_file_and_are_catchable_as_sb3s(saved_model, tmp_path):
    from sb3_adc.common.model_files import ModelFileError

    for name, (path, sb3_type) in damaged_copies(saved_model, tmp_path).items():
        with pytest.raises(ModelFileError) as error:
            ADC.load(path)
        assert isinstance(error.value, sb3_type), (name, sb3_type)
        assert isinstance(error.value, ValueError)
        assert path.name in str(error.value)
    # The errors of a file of another algorithm, or for another environment, keep SB3's types too.
    with pytest.raises(ValueError, match=r"Cannot load the ADC model .*adc\.zip.*Action spaces do not match"):
        ADC.load(saved_model, env=pendulum_with(spaces.Box(-1.0, 1.0, (2,), np.float32)))


def test_load_errors_survive_pickling(tmp_path):
    # Errors cross process boundaries (SubprocVecEnv, pytest-xdist, multiprocessing pools) as pickles.
    import pickle

    path = tmp_path / "corrupt.zip"
    path.write_bytes(b"PK\x03\x04 not really a zip archive")
    with pytest.raises(ValueError, match=r"corrupt\.zip") as error:
        ADC.load(path)
    copy = pickle.loads(pickle.dumps(error.value))
    assert type(copy) is type(error.value)
    assert str(copy) == str(error.value)


def test_set_parameters_across_action_dimensions_names_the_shapes(tmp_path):
    two_dims = pendulum_with(spaces.Box(-1.0, 1.0, (2,), np.float32))
    path = tmp_path / "two.zip"
    ADC("MlpPolicy", two_dims, policy_kwargs=TINY).save(path)
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY)
    before = [p.detach().clone() for p in model.policy.parameters()]
    for parameters in (str(path), ADC.load(path).get_parameters()):
        # A RuntimeError as torch's size mismatch is in SB3, and a ValueError with the shapes and the spaces.
        with pytest.raises(RuntimeError, match=r"do not fit this ADC model .*\(2, 8\) vs \(1, 8\).*action space Box"):
            model.set_parameters(parameters)
        with pytest.raises(ValueError, match="same spaces and network sizes"):
            model.set_parameters(parameters, exact_match=False)
    # Nothing was half-loaded.
    for old, new in zip(before, model.policy.parameters(), strict=True):
        assert th.equal(old, new)
