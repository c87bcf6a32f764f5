"""Model files in the wrong class: an ADC file is never trained as another algorithm's model, and back."""

import pickle
import re
import warnings

import gymnasium as gym
import pytest
import torch as th
from stable_baselines3 import DDPG, TD3
from stable_baselines3.common.buffers import NStepReplayBuffer

from sb3_adc import ADC
from sb3_adc.baselines import AveragedActorTD3, SplitRateDDPG, VanillaActorCritic
from sb3_adc.common.model_files import LOADED_N_STEP_WARNING, ModelFileError, model_file_error


@pytest.fixture(scope="module")
def adc_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("adc") / "adc.zip"
    ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8], n_intervals=4), seed=0).save(path)
    return path


@pytest.mark.parametrize("algorithm", [SplitRateDDPG, AveragedActorTD3, VanillaActorCritic])
def test_ddpg_baselines_refuse_an_adc_file(adc_file, algorithm):
    with pytest.raises(TypeError, match=r"adc\.zip.*got the ADC policy \w+.*Load it with sb3_adc\.ADC\.load"):
        algorithm.load(adc_file)


def test_sb3_ddpg_loads_an_adc_file_silently(adc_file):
    # SB3's own DDPG builds whatever policy class the file names: the documented reason to load ADC files with ADC
    # (docs/guide/robustness.rst). If SB3 starts refusing them, the docs can say so.
    model = DDPG.load(adc_file)
    assert type(model.policy).__module__ == "sb3_adc.adc.policies"


def test_split_rate_ddpg_still_loads_ddpg_files(tmp_path):
    path = tmp_path / "ddpg.zip"
    DDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8]), seed=0).save(path)
    model = SplitRateDDPG.load(path)
    assert type(model.policy).__name__ == "TD3Policy"
    with pytest.raises(FileNotFoundError, match=r"No SplitRateDDPG model file at .*other\.zip$"):
        SplitRateDDPG.load(tmp_path / "other.zip")


@pytest.mark.parametrize("catchable_as", [ValueError, KeyError, EOFError, RuntimeError, AssertionError, TypeError])
def test_model_file_errors_are_also_the_type_sb3_raises(catchable_as):
    error = model_file_error("x.zip: damaged", catchable_as)
    assert isinstance(error, ModelFileError)
    assert isinstance(error, catchable_as)
    assert isinstance(error, ValueError)
    assert str(error) == "x.zip: damaged"  # not quoted, although KeyError quotes its message
    copy = pickle.loads(pickle.dumps(error))
    assert type(copy) is type(error)
    assert str(copy) == str(error)


def test_an_error_type_that_cannot_be_combined_still_gives_a_model_file_error():
    # UnicodeDecodeError needs five arguments: the error is a plain ModelFileError (a ValueError, as it is too).
    error = model_file_error("x.zip: bad text", UnicodeDecodeError)
    assert isinstance(error, ModelFileError)
    assert str(error) == "x.zip: bad text"


def n_step_warnings(caught):
    return [str(w.message) for w in caught if re.search(LOADED_N_STEP_WARNING, str(w.message))]


@pytest.mark.parametrize("algorithm", [ADC, TD3])
def test_loading_an_n_step_model_keeps_its_returns_without_sb3s_warning(tmp_path, algorithm):
    # SB3 warns on every load of an n-step model that its n_steps "is ignored"; the loaded buffer does use them.
    # ADC's own load and the engine's (every algorithm's runs) stay quiet; SB3's TD3.load is SB3's to mend.
    from sb3_adc.config import resolve_entry
    from sb3_adc.experiment.enjoy import load_model

    path = tmp_path / "n_step.zip"
    algorithm("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8]), n_steps=3, gamma=0.9, seed=0).save(path)
    config = resolve_entry(algorithm.__name__.lower(), "Pendulum-v1", {"policy": "MlpPolicy", "n_timesteps": 64}, "test")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loaded = [load_model(config, str(path))]
        if algorithm is ADC:
            loaded.append(ADC.load(path, env=gym.make("Pendulum-v1")))
    assert n_step_warnings(caught) == []
    for model in loaded:
        assert model.replay_buffer_class is NStepReplayBuffer
        assert model.replay_buffer_kwargs == {"n_steps": 3, "gamma": 0.9}
    if algorithm is ADC:
        # The model loaded to train learns from 3-step returns: bootstrapped with gamma**3, not gamma.
        model = loaded[-1]
        model.learn(64)
        samples = model.replay_buffer.sample(32)
        assert samples.discounts is not None
        assert th.isclose(samples.discounts.min(), th.tensor(0.9**3)).item()


def test_a_genuine_n_step_warning_still_shows():
    # Outside a load, the warning SB3 gives a user who passes the class without its n_steps stays.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        TD3("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8]), n_steps=3, replay_buffer_class=NStepReplayBuffer)
    assert len(n_step_warnings(caught)) == 1
