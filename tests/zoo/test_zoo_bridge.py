"""``python -m sb3_adc.zoo``: the RL Zoo's command names on sb3-adc's engine (the Zoo's ExperimentManager subclassed)."""

import os
import subprocess
import sys
import textwrap

import pytest
import yaml

pytest.importorskip("rl_zoo3")

from sb3_adc import ADC
from sb3_adc.baselines import AveragedActorTD3, DuelingDQNPolicy, SplitRateDDPG
from sb3_adc.common.noise import EpsilonGaussianNoise
from sb3_adc.zoo import main

CONF = """
    Pendulum-v1:
      n_timesteps: 300
      policy: MlpPolicy
      learning_starts: 100
      batch_size: 16
      noise_type: epsilon-normal
      noise_std: 0.1
      n_intervals: 10
      policy_kwargs: "dict(net_arch=[8], value_net_arch=[4])"
      env_kwargs: {max_episode_steps: 50}
"""
DQN_CONF = """
    Pendulum-v1:
      n_timesteps: 200
      policy: sb3_adc.baselines.DuelingDQNPolicy
      env_wrapper:
        - sb3_adc_envs.wrappers.DiscretizedActions: {n_actions: 25}
      learning_starts: 100
      policy_kwargs: "dict(net_arch=[8], value_net_arch=[4], advantage_net_arch=[4])"
      env_kwargs: {max_episode_steps: 50}
"""


def write_conf(folder, text, name="adc.yml"):
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return str(path)


@pytest.fixture(scope="module")
def zoo_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("zoo")
    conf = write_conf(folder, CONF)
    logs = folder / "logs"
    args = ["train", "--algo", "adc", "--env", "Pendulum-v1", "-conf", conf, "-f", str(logs), "--seed", "0"]
    assert main([*args, "--eval-freq", "100", "--eval-episodes", "1", "--num-threads", "1", "-params", "batch_size:8"]) == 0
    return logs / "adc" / "Pendulum-v1_1"


def test_zoo_train_runs_adc_with_our_hyperparameters(zoo_run):
    for name in ("Pendulum-v1.zip", "best_model.zip", "evaluations.npz", "0.monitor.csv"):
        assert (zoo_run / name).is_file(), name
    model = ADC.load(zoo_run / "Pendulum-v1.zip")
    assert model.num_timesteps == 300
    assert model.policy.n_intervals == 10
    assert model.batch_size == 8
    assert isinstance(model.action_noise, EpsilonGaussianNoise)
    assert model.action_noise.decay_steps == 150
    # Plain YAML (the Zoo would write Python tags), with the resolved entry.
    config = yaml.safe_load((zoo_run / "Pendulum-v1" / "config.yml").read_text())
    assert config["policy_kwargs"] == "dict(net_arch=[8], value_net_arch=[4])"
    assert config["batch_size"] == 8
    args = yaml.safe_load((zoo_run / "Pendulum-v1" / "args.yml").read_text())
    assert (args["algo"], args["env_id"]) == ("adc", "Pendulum-v1")


def test_zoo_train_runs_on_the_zoo_experiment_manager(monkeypatch, tmp_path):
    """The engine is the Zoo's ExperimentManager: its setup_experiment, learn and save_trained_model run."""
    from rl_zoo3.exp_manager import ExperimentManager

    from sb3_adc.experiment.manager import RunManager

    assert issubclass(RunManager, ExperimentManager)
    calls = []
    for name in ("setup_experiment", "learn", "save_trained_model"):
        original = getattr(RunManager, name)
        monkeypatch.setattr(RunManager, name, lambda self, *a, _f=original, _n=name: calls.append(_n) or _f(self, *a))
    conf = write_conf(tmp_path, CONF)
    args = ["train", "--algo", "adc", "--env", "Pendulum-v1", "-conf", conf, "-f", str(tmp_path / "logs"), "-n", "60"]
    assert main([*args, "--eval-freq", "-1"]) == 0
    assert calls == ["setup_experiment", "learn", "save_trained_model"]


def test_zoo_enjoy_plays_the_run(zoo_run, capsys):
    logs = zoo_run.parent.parent
    args = ["enjoy", "--algo", "adc", "--env", "Pendulum-v1", "-f", str(logs), "--no-render", "-n", "2", "--load-best"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "best_model.zip" in out
    assert out.count("length 50") == 2


def test_zoo_enjoy_never_executes_a_tampered_config(zoo_run, tmp_path, capsys):
    tampered = tmp_path / "logs" / "adc" / "Pendulum-v1_1"
    tampered.mkdir(parents=True)
    for name in ("Pendulum-v1.zip",):
        (tampered / name).write_bytes((zoo_run / name).read_bytes())
    (tampered / "Pendulum-v1").mkdir()
    (tampered / "Pendulum-v1" / "args.yml").write_text((zoo_run / "Pendulum-v1" / "args.yml").read_text())
    marker = tmp_path / "pwned"
    (tampered / "Pendulum-v1" / "config.yml").write_text(f"n_timesteps: !!python/object/apply:os.system ['touch {marker}']\n")
    assert main(["enjoy", "--algo", "adc", "--env", "Pendulum-v1", "-f", str(tmp_path / "logs"), "--no-render", "-n=1"]) == 2
    assert "config.yml: file is not valid YAML (Python tags are not accepted)" in capsys.readouterr().err
    assert not marker.exists()


def test_zoo_enjoy_stops_an_alias_bomb(zoo_run, tmp_path, capsys):
    run_dir = tmp_path / "logs" / "adc" / "Pendulum-v1_1"
    (run_dir / "Pendulum-v1").mkdir(parents=True)
    (run_dir / "Pendulum-v1.zip").write_bytes((zoo_run / "Pendulum-v1.zip").read_bytes())
    (run_dir / "Pendulum-v1" / "config.yml").write_text((zoo_run / "Pendulum-v1" / "config.yml").read_text())
    bomb = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"a{level}: &a{level} [{', '.join([f'*a{level - 1}'] * 9)}]\n" for level in range(1, 9)
    )
    (run_dir / "Pendulum-v1" / "args.yml").write_text(bomb)
    assert main(["enjoy", "--algo", "adc", "--env", "Pendulum-v1", "-f", str(tmp_path / "logs"), "--no-render", "-n=1"]) == 2
    assert "args.yml: file is over a limit of sb3_adc.config.yaml_files" in capsys.readouterr().err


def test_zoo_params_are_parsed_not_evaluated(tmp_path, capsys):
    conf = write_conf(tmp_path, CONF)
    marker = tmp_path / "pwned"
    attack = f"policy_kwargs:dict(net_arch=__import__('os').system('touch {marker}'))"
    assert main(["train", "--algo", "adc", "--env", "Pendulum-v1", "-conf", conf, "-f", str(tmp_path), "-params", attack]) == 2
    assert "function calls are not allowed" in capsys.readouterr().err
    assert not marker.exists()
    assert not (tmp_path / "adc").exists()  # nothing written


def test_zoo_dqn_with_the_dueling_policy_and_discretized_actions(tmp_path):
    conf = write_conf(tmp_path, DQN_CONF, "dqn.yml")
    args = ["train", "--algo", "dqn", "--env", "Pendulum-v1", "-conf", conf, "-f", str(tmp_path / "logs"), "--eval-freq", "-1"]
    assert main(args) == 0
    from stable_baselines3 import DQN

    model = DQN.load(tmp_path / "logs" / "dqn" / "Pendulum-v1_1" / "Pendulum-v1.zip")
    assert isinstance(model.policy, DuelingDQNPolicy)
    assert model.action_space.n == 25


def test_zoo_algos_table_and_usage(capsys):
    from rl_zoo3.utils import ALGOS

    from sb3_adc.zoo import register_algorithms

    register_algorithms()
    assert ALGOS["adc"] is ADC
    assert ALGOS["ddpg"] is SplitRateDDPG
    assert ALGOS["td3"] is AveragedActorTD3
    assert main([]) == 2
    assert "usage: python -m sb3_adc.zoo {train,enjoy}" in capsys.readouterr().err


def test_python_m_sb3_adc_zoo_help_from_another_directory(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "sb3_adc.zoo", "train", "--help"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )
    assert result.returncode == 0
    assert "{" in result.stdout
    assert "adc" in result.stdout.split("--algo")[1].split("}")[0]


def test_zoo_optimize_draws_from_our_search_space(tmp_path, capsys):
    """-optimize tunes ADC with sb3-adc's sampler: its critic knobs are searched, -params stay fixed."""
    conf = write_conf(tmp_path, CONF)
    logs = tmp_path / "logs"
    args = ["train", "--algo", "adc", "--env", "Pendulum-v1", "-conf", conf, "-f", str(logs), "--seed", "0"]
    extra = ["-optimize", "--n-trials", "2", "--n-evaluations", "1", "--eval-episodes", "1", "-n", "200"]
    extra += ["--sampler", "random", "--pruner", "none", "--num-threads", "1", "-params", "gamma:0.5"]
    storage = tmp_path / "study.log"
    assert main([*args, *extra, "--storage", str(storage), "--study-name", "zoo"]) == 0
    import optuna

    study = optuna.load_study(
        study_name="zoo", storage=optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(str(storage)))
    )
    assert len(study.trials) == 2
    assert all(trial.state == optuna.trial.TrialState.COMPLETE for trial in study.trials)
    assert study.trials[0].params == {}  # the first trial is the entry itself
    drawn = study.trials[1].params
    assert "critic_design" in drawn
    assert "n_intervals" in drawn
    assert "gamma" not in drawn


def test_the_zoos_own_objective_tunes_adc_with_our_search_space(tmp_path):
    """register_algorithms puts ADC's space in the Zoo's sampler table (its own spaces stay): the Zoo's
    ExperimentManager then runs a trial of ADC whose drawn values are ours, validated as an entry."""
    import argparse

    import optuna
    from rl_zoo3.exp_manager import ExperimentManager
    from rl_zoo3.hyperparams_opt import HYPERPARAMS_SAMPLER, sample_td3_params

    from sb3_adc.zoo import register_algorithms

    register_algorithms()
    assert HYPERPARAMS_SAMPLER["td3"] is sample_td3_params
    conf = tmp_path / "adc.yml"
    conf.write_text("Pendulum-v1:\n  n_timesteps: 200\n  policy: MlpPolicy\n")
    storage = str(tmp_path / "study.log")
    manager = ExperimentManager(
        argparse.Namespace(), "adc", "Pendulum-v1", str(tmp_path), optimize_hyperparameters=True, n_trials=1,
        n_timesteps=200, n_evaluations=1, n_eval_episodes=1, config=str(conf), sampler="random", pruner="none",
        storage=storage, study_name="zoo", n_startup_trials=0, seed=0, verbose=0,
    )  # fmt: skip
    assert manager.setup_experiment() is None
    manager.hyperparameters_optimization()
    backend = optuna.storages.journal.JournalFileBackend(storage)
    (trial,) = optuna.load_study(study_name="zoo", storage=optuna.storages.JournalStorage(backend)).trials
    assert trial.state == optuna.trial.TrialState.COMPLETE
    assert {"critic_design", "n_intervals", "critic_rate_ratio", "noise_type"} <= set(trial.params)


def test_zoo_sampler_returns_validated_constructor_keywords():
    import optuna

    from sb3_adc.common.noise import EpsilonGaussianNoise
    from sb3_adc.experiment.samplers import zoo_sampler

    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    study.enqueue_trial({"noise_type": "epsilon-normal", "noise_std": 0.2, "critic_design": "paper"})
    kwargs = zoo_sampler("adc")(study.ask(), 3, 1, {})
    assert isinstance(kwargs["action_noise"], EpsilonGaussianNoise)
    assert kwargs["action_noise"]().shape == (3,)
    assert kwargs["policy_kwargs"]["critic_design"] == "paper"
    assert "policy" not in kwargs
    ADC("MlpPolicy", "Pendulum-v1", **{**kwargs, "action_noise": None}).learn(10)
