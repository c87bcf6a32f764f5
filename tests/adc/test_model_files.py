"""Model files in the wrong class: an ADC file is never trained as another algorithm's model, and back."""

import pickle

import pytest
from stable_baselines3 import DDPG

from sb3_adc import ADC
from sb3_adc.baselines import SplitRateDDPG, VanillaActorCritic
from sb3_adc.common.model_files import ModelFileError, model_file_error


@pytest.fixture(scope="module")
def adc_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("adc") / "adc.zip"
    ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[8], n_intervals=4), seed=0).save(path)
    return path


@pytest.mark.parametrize("algorithm", [SplitRateDDPG, VanillaActorCritic])
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
