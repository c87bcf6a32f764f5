"""The shipped hyperparameter files: complete (every registered environment, every algorithm) and valid."""

import gymnasium as gym
import pytest

import sb3_adc  # noqa: F401 (registers the environments)
from sb3_adc.config import ALGORITHMS, packaged_hyperparams_file, read_hyperparams_file, resolve_entry, select_entry
from sb3_adc.config.loader import find_hyperparams_file, shipped_hyperparams_files
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


def test_adc_and_ddpg_defaults_differ_only_by_the_critic():
    # The tuned Pendulum entries are a drop-in comparison: same settings, ADC's critic options aside.
    adc = read_hyperparams_file(packaged_hyperparams_file("adc"))
    ddpg = read_hyperparams_file(packaged_hyperparams_file("ddpg"))
    for env_id in PAPER_ENVS:
        assert {k: v for k, v in adc[env_id].items() if k != "n_intervals"} == ddpg[env_id]


PAPER_ALGORITHMS = ("adc", "ddpg", "vanilla_ac", "dqn")
#: The paper's Tables 1 (Pendulum) and 3 (noisy Pendulum): gamma, actor learning rate, batch, buffer, tau.
PAPER_TABLES = {
    "Pendulum-v1": {"gamma": 0.9, "learning_rate": 1e-3, "batch_size": 32, "buffer_size": 5000, "tau": 0.01},
    "sb3_adc/NoisyPendulum-v1": {"gamma": 0.9, "learning_rate": 1e-4, "batch_size": 32, "buffer_size": 5000, "tau": 0.01},
}


def test_paper_files_are_shipped_by_name():
    assert {f"paper/{algo}" for algo in PAPER_ALGORITHMS} <= set(shipped_hyperparams_files())
    assert find_hyperparams_file("paper/adc") == packaged_hyperparams_file("paper/adc")


@pytest.mark.parametrize("algo", PAPER_ALGORITHMS)
@pytest.mark.parametrize("env_id", PAPER_ENVS)
def test_paper_files_hold_the_papers_tables(algo, env_id):
    path = packaged_hyperparams_file(f"paper/{algo}")
    entry, source = select_entry(read_hyperparams_file(path), env_id, path)
    config = resolve_entry(algo, env_id, entry, source)
    kwargs = config.model_kwargs
    table = PAPER_TABLES[env_id]
    assert kwargs["gamma"] == table["gamma"]
    assert kwargs["learning_rate"] == pytest.approx(table["learning_rate"])
    if algo in ("adc", "ddpg", "vanilla_ac"):
        # Actor-critics: a critic learning rate twice the actor's (a: / c: in the tables).
        assert kwargs["critic_learning_rate"] == pytest.approx(2 * table["learning_rate"])
    if algo in ("adc", "ddpg", "dqn"):
        assert kwargs["batch_size"] == table["batch_size"]
        assert kwargs["buffer_size"] == table["buffer_size"]
    if algo in ("adc", "ddpg"):
        assert kwargs["tau"] == table["tau"]
    if algo == "adc":
        # The paper's Pendulum network: one hidden layer of 30, 100 intervals, a value stream of 20.
        assert kwargs["policy_kwargs"]["net_arch"] == {"pi": [30], "qf": [30]}
        assert kwargs["policy_kwargs"]["n_intervals"] == 100
        assert kwargs["policy_kwargs"]["value_net_arch"] == [20]


TABLE_2 = {"gamma": 0.9, "buffer_size": 5000, "batch_size": 16, "learning_rate": 1e-4, "tau": 0.01}


@pytest.mark.parametrize("algo", ["adc", "ddpg", "td3"])
def test_paper_files_hold_table_2_for_the_lidar_course(algo):
    env_id = "sb3_adc/LidarObstacleCourse-v0"
    path = packaged_hyperparams_file(f"paper/{algo}")
    entry, source = select_entry(read_hyperparams_file(path), env_id, path)
    kwargs = resolve_entry(algo, env_id, entry, source).model_kwargs
    assert {key: kwargs[key] for key in TABLE_2} == pytest.approx(TABLE_2)
    assert kwargs["policy_kwargs"]["net_arch"] == (
        {"pi": [100, 20], "qf": [100]} if algo == "adc" else {"pi": [100, 20], "qf": [100, 20]}
    )
    if algo != "td3":
        assert kwargs["critic_learning_rate"] == pytest.approx(2e-4)
    if algo == "adc":
        assert kwargs["policy_kwargs"]["n_intervals"] == 100
        assert kwargs["policy_kwargs"]["value_net_arch"] == [20]
