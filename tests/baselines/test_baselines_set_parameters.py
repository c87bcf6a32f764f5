"""``set_parameters`` of the DDPG baselines: parameters of another shape give ADC's clear error, nothing half-loaded."""

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces

from sb3_adc.baselines import AveragedActorTD3, SplitRateDDPG, VanillaActorCritic
from sb3_adc.common.model_files import ModelFileError

TINY = dict(net_arch=[8])


class TwoActionPendulum(gym.ActionWrapper):
    """Pendulum with a two-dimensional action space (the first dimension is applied)."""

    def __init__(self):
        super().__init__(gym.make("Pendulum-v1"))
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)

    def action(self, action):
        return action[:1]


@pytest.mark.parametrize("algorithm", [SplitRateDDPG, AveragedActorTD3, VanillaActorCritic])
def test_set_parameters_across_action_dimensions_names_the_shapes(tmp_path, algorithm):
    path = tmp_path / "two.zip"
    algorithm("MlpPolicy", TwoActionPendulum(), policy_kwargs=TINY).save(path)
    model = algorithm("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY)
    before = [parameter.detach().clone() for parameter in model.policy.parameters()]
    name = algorithm.__name__
    for parameters in (str(path), algorithm.load(path).get_parameters()):
        # A RuntimeError as torch's size mismatch is in SB3, and a ValueError naming the tensors and the spaces.
        with pytest.raises(RuntimeError, match=rf"do not fit this {name} model .*\(2, 8\) vs \(1, 8\).*action space Box"):
            model.set_parameters(parameters)
        with pytest.raises(ValueError, match="same spaces and network sizes") as error:
            model.set_parameters(parameters, exact_match=False)
        assert isinstance(error.value, ModelFileError)
    # Nothing was half-loaded.
    for old, new in zip(before, model.policy.parameters(), strict=True):
        assert th.equal(old, new)


def test_set_parameters_of_a_damaged_file_names_it(tmp_path):
    path = tmp_path / "damaged.zip"
    path.write_bytes(b"PK\x03\x04 not a zip archive")
    model = SplitRateDDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY)
    with pytest.raises(ModelFileError, match=r"Cannot load the SplitRateDDPG model .*damaged\.zip"):
        model.set_parameters(str(path))


def test_set_parameters_of_the_same_shapes_still_loads(tmp_path):
    source = SplitRateDDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, seed=1)
    path = tmp_path / "same.zip"
    source.save(path)
    model = SplitRateDDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, seed=2)
    model.set_parameters(str(path))
    for saved, loaded in zip(source.policy.parameters(), model.policy.parameters(), strict=True):
        assert th.equal(saved, loaded)
