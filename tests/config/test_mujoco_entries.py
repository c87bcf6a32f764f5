"""The MuJoCo entries (issue 63): sb3-contrib's TQC and CrossQ registered, every new entry resolves, the baselines'
entries are the RL Zoo's published settings at the experiment's budget, and each builds and steps where mujoco is
installed (the ``mujoco`` extra)."""

from pathlib import Path

import gymnasium as gym
import pytest
import yaml

from sb3_adc.config import (
    ALGORITHMS,
    HyperparamsError,
    get_algorithm,
    load_hyperparams,
    packaged_hyperparams_file,
    read_hyperparams_file,
)

ALGOS = ("adc", "ddpg", "td3", "sac", "tqc", "crossq")
ENVS = ("Hopper-v5", "HalfCheetah-v5")
BUDGET = 300_000
#: The Zoo's ids of the same tasks in its hyperparameter files.
ZOO_IDS = {"Hopper-v5": "Hopper-v4", "HalfCheetah-v5": "HalfCheetah-v4"}


def test_tqc_and_crossq_are_registered_as_sb3_contribs():
    sb3_contrib = pytest.importorskip("sb3_contrib")
    assert {"tqc", "crossq"} <= set(ALGORITHMS.names())
    assert get_algorithm("tqc") is sb3_contrib.TQC
    assert get_algorithm("crossq") is sb3_contrib.CrossQ


@pytest.mark.parametrize("algo", ["tqc", "crossq"])
def test_the_new_files_have_a_default_and_registered_environments(algo):
    content = read_hyperparams_file(packaged_hyperparams_file(algo))
    assert content["default"] == {"n_timesteps": 100_000, "policy": "MlpPolicy"}
    assert all(name == "default" or name in gym.registry for name in content)


@pytest.mark.parametrize("env_id", ENVS)
@pytest.mark.parametrize("algo", ALGOS)
def test_every_mujoco_entry_resolves_at_the_experiment_budget(algo, env_id):
    config = load_hyperparams(algo, env_id)
    assert config.algorithm_class is get_algorithm(algo)
    assert config.n_timesteps == BUDGET
    assert config.saved["n_timesteps"] == BUDGET


@pytest.mark.parametrize("env_id", ENVS)
@pytest.mark.parametrize("algo", ["ddpg", "td3", "sac", "tqc", "crossq"])
def test_the_baselines_entries_are_the_rl_zoos_but_the_budget(algo, env_id):
    rl_zoo3 = pytest.importorskip("rl_zoo3")
    zoo_file = Path(rl_zoo3.__file__).parent / "hyperparams" / f"{algo}.yml"
    zoo = yaml.safe_load(zoo_file.read_text(encoding="utf-8"))[ZOO_IDS[env_id]]
    ours = read_hyperparams_file(packaged_hyperparams_file(algo))[env_id]
    assert ours.pop("n_timesteps") == BUDGET
    assert zoo.pop("n_timesteps") >= 1e6
    assert ours == zoo


@pytest.mark.parametrize("env_id", ENVS)
def test_adcs_entry_is_td3s_recipe_with_its_default_critic(env_id):
    kwargs = load_hyperparams("adc", env_id).model_kwargs
    assert kwargs["policy_kwargs"]["net_arch"] == [256, 256]
    assert kwargs["policy_kwargs"]["n_critics"] == 2
    assert kwargs["policy_kwargs"]["critic_design"] == "legendre"
    expected = {
        "batch_size": 256,
        "learning_rate": 1e-3,
        "critic_learning_rate": 1e-3,
        "learning_starts": 10_000,
        "policy_delay": 2,
        "target_policy_noise": 0.2,
        "target_noise_clip": 0.5,
    }
    assert {key: kwargs[key] for key in expected} == expected
    noise = load_hyperparams("adc", env_id).noise
    assert noise is not None
    assert (noise.noise_type, noise.std) == ("normal", 0.1)


def test_tqc_and_crossq_keys_are_accepted_and_checked():
    config = load_hyperparams(
        "tqc", "Hopper-v5", overrides={"policy_kwargs": "dict(n_quantiles=10, n_critics=3, net_arch=[16])"}
    )
    assert config.model_kwargs["top_quantiles_to_drop_per_net"] == 5
    assert config.model_kwargs["policy_kwargs"] == {"n_quantiles": 10, "n_critics": 3, "net_arch": [16]}
    assert load_hyperparams("crossq", "Hopper-v5").model_kwargs["policy_delay"] == 3
    with pytest.raises(HyperparamsError, match="policy_delay"):
        load_hyperparams("crossq", "Hopper-v5", overrides={"policy_delay": 0})


#: Small networks for a short run (an override of ``policy_kwargs`` replaces the entry's mapping).
SMALL_NETWORKS = {
    "adc": "dict(net_arch=[16], n_critics=2)",
    "crossq": "dict(net_arch=dict(pi=[16], qf=[16]))",
}


@pytest.mark.parametrize("algo", ALGOS)
def test_each_entry_builds_and_learns_on_hopper(algo):
    pytest.importorskip("mujoco")
    small = {
        "learning_starts": 20,
        "batch_size": 8,
        "buffer_size": 1000,
        "policy_kwargs": SMALL_NETWORKS.get(algo, "dict(net_arch=[16])"),
    }
    config = load_hyperparams(algo, "Hopper-v5", overrides=small)
    env = gym.make("Hopper-v5")
    assert env.action_space.shape == (3,)
    noise = config.make_action_noise(env.action_space)
    model = config.algorithm_class(env=env, action_noise=noise, seed=0, **config.model_kwargs)
    model.learn(40)
    assert model.num_timesteps == 40


def test_tqc_quantiles_to_drop_are_checked_when_read():
    with pytest.raises(HyperparamsError, match="`top_quantiles_to_drop_per_net`: expected an integer >= 0"):
        load_hyperparams("tqc", "Hopper-v5", overrides={"top_quantiles_to_drop_per_net": "five"})
