"""The shipped hyperparameter files: complete (every registered environment, every algorithm) and valid."""

import gymnasium as gym
import pytest

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc.config import ALGORITHMS, packaged_hyperparams_file, read_hyperparams_file, resolve_entry, select_entry
from sb3_adc_envs.registration import ENV_SPECS

SHIPPED_ALGORITHMS = ("adc", "ddpg", "td3", "sac", "dqn", "vanilla_ac")
PAPER_ENVS = ("Pendulum-v1", "sb3_adc/NoisyPendulum-v1")


def test_every_algorithm_has_a_file():
    assert set(SHIPPED_ALGORITHMS) <= set(ALGORITHMS.names())
    for algo in SHIPPED_ALGORITHMS:
        assert read_hyperparams_file(packaged_hyperparams_file(algo))


@pytest.mark.parametrize("algo", SHIPPED_ALGORITHMS)
def test_every_registered_environment_has_an_entry(algo):
    content = read_hyperparams_file(packaged_hyperparams_file(algo))
    missing = [env_id for env_id in (*PAPER_ENVS, *ENV_SPECS) if env_id not in content]
    assert not missing, f"{algo}.yml has no entry for {missing}"


@pytest.mark.parametrize("algo", SHIPPED_ALGORITHMS)
def test_every_entry_is_a_registered_environment_and_resolves(algo):
    path = packaged_hyperparams_file(algo)
    content = read_hyperparams_file(path)
    for name in content:
        assert name == "default" or name in gym.registry, f"{path}: {name!r} is not a registered environment id"
        if name == "default":
            continue
        entry, source = select_entry(content, name, path)
        config = resolve_entry(algo, name, entry, source)
        assert config.n_timesteps > 0
        if algo in ("ddpg", "vanilla_ac") and name in PAPER_ENVS:
            # The paper's baselines: gamma 0.9 and a critic learning rate twice the actor's (Tables 1 and 3).
            assert config.model_kwargs["gamma"] == 0.9
            assert config.model_kwargs["critic_learning_rate"] == pytest.approx(2 * config.model_kwargs["learning_rate"])
