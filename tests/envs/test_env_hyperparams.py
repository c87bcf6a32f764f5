"""The hyperparameter entries of the environments load, build their models, and keep the paper's network."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest

from sb3_adc.config import packaged_hyperparams_file, read_hyperparams_file, resolve_entry, select_entry
from sb3_adc.config.loader import load_hyperparams

RESULTS = Path(__file__).resolve().parents[2] / "benchmarks" / "results"
HIGHWAY = "sb3_adc/HighwayObstacle-v1"

#: The entries with the paper's networks (the tuned highway -v1 entries have their own: see the test below).
ENV_IDS = [
    "sb3_adc/LidarObstacleCourse-v0",
    "sb3_adc/LidarObstacleCourseNoisy-v0",
    "sb3_adc/LidarObstacleCourse-v1",
    "sb3_adc/LidarObstacleCourseNoisy-v1",
    "sb3_adc/HighwayObstacle-v0",
]
#: The entries that hold a configuration measured on the procedural course instead of the -v0 entry's.
MEASURED_V1 = {
    (algo, env_id)
    for algo in ("adc", "ddpg", "sac", "td3")
    for env_id in ("sb3_adc/LidarObstacleCourse-v1", "sb3_adc/LidarObstacleCourseNoisy-v1")
}


@pytest.mark.parametrize("algo", ["adc", "ddpg", "td3"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_entries_load_and_build_a_model(algo, env_id):
    config = load_hyperparams(algo, env_id)
    assert config.source.endswith(f"[{env_id}]")  # the environment's own entry, not `default`
    kwargs = dict(config.model_kwargs)
    assert kwargs["policy_kwargs"]["net_arch"]["pi"] == [100, 20]  # the paper's actor
    assert kwargs["tau"] == 0.01
    # ADC's, DDPG's and TD3's -v1 entries hold the configurations measured on -v1 (tests/results/test_procedural_results.py).
    assert kwargs["gamma"] == (0.98 if (algo, env_id) in MEASURED_V1 else 0.9)
    train_briefly(config, env_id)


def train_briefly(config, env_id: str, **overrides) -> None:
    """Build the entry's model on its environment and train it for 50 steps (``overrides``: of its keywords)."""
    env = gym.make(env_id, **config.env_kwargs)
    kwargs = {**config.model_kwargs, **overrides}
    policy = kwargs.pop("policy")
    model = config.algorithm_class(policy, env, action_noise=config.make_action_noise(env.action_space), seed=0, **kwargs)
    model.learn(50)
    env.close()


@pytest.mark.parametrize("env_id", [env_id for algo, env_id in sorted(MEASURED_V1) if algo == "sac"])
def test_the_measured_sac_entries_load_and_build_a_model(env_id):
    """SAC's -v1 entries (its own network, not the paper's) load and train; what they hold is checked against its
    pre-registered sweep in tests/results/test_procedural_results.py."""
    config = load_hyperparams("sac", env_id)
    assert config.source.endswith(f"[{env_id}]")
    assert config.model_kwargs["gamma"] == 0.98
    train_briefly(config, env_id, learning_starts=10)  # its warm-up is 10,000 steps: train within the 50


def test_adc_entry_uses_the_paper_dueling_critic():
    kwargs = load_hyperparams("adc", "sb3_adc/LidarObstacleCourse-v0").model_kwargs
    policy_kwargs = kwargs["policy_kwargs"]
    paper = {"net_arch": {"pi": [100, 20], "qf": [100]}, "value_net_arch": [20], "n_intervals": 100}
    assert {key: policy_kwargs[key] for key in paper} == paper
    assert policy_kwargs.get("critic_design", "paper") == "paper"
    assert kwargs["critic_learning_rate"] == 2 * kwargs["learning_rate"]


@pytest.mark.parametrize("algo", ["adc", "ddpg"])
def test_the_paper_files_hold_table_2(algo):
    path = packaged_hyperparams_file(f"paper/{algo}")
    entry, source = select_entry(read_hyperparams_file(path), "sb3_adc/LidarObstacleCourse-v0", path)
    kwargs = resolve_entry(algo, "sb3_adc/LidarObstacleCourse-v0", entry, source).model_kwargs
    table_2 = {"gamma": 0.9, "buffer_size": 5000, "batch_size": 16, "tau": 0.01}
    table_2.update(learning_rate=1e-4, critic_learning_rate=2e-4)
    assert {key: kwargs[key] for key in table_2} == table_2
    critic = {"qf": [100], "value_net_arch": [20], "n_intervals": 100} if algo == "adc" else {"qf": [100, 20]}
    assert kwargs["policy_kwargs"]["net_arch"] == {"pi": [100, 20], "qf": critic.pop("qf")}
    assert {key: kwargs["policy_kwargs"][key] for key in critic} == critic


@pytest.mark.parametrize("algo", ["dqn", "vanilla_ac"])
@pytest.mark.parametrize("noisy", ["", "Noisy"])
def test_v1_entries_start_from_the_v0_entries(algo, noisy):
    v0 = load_hyperparams(algo, f"sb3_adc/LidarObstacleCourse{noisy}-v0")
    v1 = load_hyperparams(algo, f"sb3_adc/LidarObstacleCourse{noisy}-v1")
    assert v1.source.endswith(f"[sb3_adc/LidarObstacleCourse{noisy}-v1]")
    # The same training settings and start jitter; the procedural layouts come from the id itself.
    assert v1.n_timesteps == v0.n_timesteps
    assert v1.env_kwargs == v0.env_kwargs
    assert "course" not in v1.env_kwargs


@pytest.mark.parametrize("algo", ["adc", "ddpg", "sac", "td3"])
def test_the_measured_noisy_v1_entries_are_their_clean_v1_entries(algo):
    clean = load_hyperparams(algo, "sb3_adc/LidarObstacleCourse-v1")
    noisy = load_hyperparams(algo, "sb3_adc/LidarObstacleCourseNoisy-v1")
    assert noisy.source.endswith("[sb3_adc/LidarObstacleCourseNoisy-v1]")
    assert noisy.saved == clean.saved


@pytest.mark.parametrize("algo", ["dqn", "vanilla_ac"])
def test_the_untuned_highway_v1_entries_are_the_v0_entries(algo):
    """-v1 is -v0 seen through more rays: the same starting entry where the equal-budget tuning left it alone."""
    v0 = load_hyperparams(algo, "sb3_adc/HighwayObstacle-v0")
    v1 = load_hyperparams(algo, "sb3_adc/HighwayObstacle-v1")
    assert v1.source.endswith("[sb3_adc/HighwayObstacle-v1]")
    assert v1.saved == v0.saved


@pytest.mark.parametrize("algo", ["adc", "ddpg", "sac", "td3"])
def test_the_highway_v1_entries_are_the_tuning_winners_and_were_the_v0_entries(algo):
    """The shipped -v1 entry is the equal-budget tuning's winner; the entry it replaced, which the committed highway
    experiments before the tuning (and the tuning's starting point) read, is the -v0 entry."""
    winner = load_hyperparams(algo, HIGHWAY, conf_file=str(RESULTS / "highway_obstacle_v1_tuning/hyperparams" / f"{algo}.yml"))
    assert load_hyperparams(algo, HIGHWAY).saved == winner.saved
    before = load_hyperparams(algo, HIGHWAY, conf_file=str(RESULTS / "highway_obstacle_v1/hyperparams" / f"{algo}.yml"))
    assert before.saved == load_hyperparams(algo, "sb3_adc/HighwayObstacle-v0").saved
    assert winner.saved != before.saved
    train_briefly(load_hyperparams(algo, HIGHWAY), HIGHWAY)
