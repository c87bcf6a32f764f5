"""
``sb3-adc train``'s RL Zoo options (``-tb``, ``-i``, ``--eval-env-kwargs``, ``--track``) and its bad input: exit
status 2 with a message naming the option and the accepted values, before any run folder is created.
"""

import glob
import os
import shutil
import sys

import numpy as np
import pytest
import torch as th
import yaml

from sb3_adc import ADC
from sb3_adc.experiment import FinalEvaluation, TrainSettings

#: A YAML "alias bomb": nine levels of nine aliases each expand to 9**9 values (387 million).
ALIAS_BOMB = "\n".join(
    [
        "a0: &a0 [x, x, x, x, x, x, x, x, x]",
        *(f"a{level}: &a{level} [{', '.join([f'*a{level - 1}'] * 9)}]" for level in range(1, 9)),
        "algo: adc",
        "env_id: Pendulum-v1",
    ]
)


@pytest.fixture(scope="module")
def trained_runs(tmp_path_factory, tiny_conf):
    """A finished 300-step run of adc and of ddpg on Pendulum-v1 (checkpoints at 200 and 300 with replay buffers)."""
    from sb3_adc.cli import main

    logs = tmp_path_factory.mktemp("trained") / "logs"
    for algo in ("adc", "ddpg"):
        args = ["train", "--algo", algo, "--env", "Pendulum-v1", "-conf", str(tiny_conf / f"{algo}.yml"), "-f", str(logs)]
        args += ["--seed", "1", "--eval-freq", "100", "--eval-episodes", "1", "--final-eval-episodes", "1"]
        assert main([*args, "--no-progress-bar"]) == 0
    return {algo: logs / algo / "Pendulum-v1_1" for algo in ("adc", "ddpg")}


@pytest.fixture
def empty_logs(tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    return logs


def policy_state(model):
    return {key: value.clone() for key, value in model.policy.state_dict().items()}


@pytest.mark.parametrize(
    ("args", "messages"),
    [
        (["--n-eval-envs", "0"], ["`n_eval_envs` must be an integer >= 1, got 0", "--n-eval-envs"]),
        (["--eval-episodes", "0"], ["`eval_episodes` must be an integer >= 1, got 0", "--eval-episodes"]),
        (["--final-eval-episodes", "0"], ["`final_eval_episodes` must be an integer >= 1, got 0", "--final-eval-episodes"]),
        (["--keep-checkpoints", "0"], ["`keep_checkpoints` must be an integer >= 1, got 0", "--keep-checkpoints"]),
        (["--device", "foo"], ["`device` must be auto, cpu, cuda, cuda:N", "got 'foo'", "--device"]),
        (
            ["--env-kwargs", "foo:1"],
            ["`env_kwargs` rejected by Pendulum-v1", "'foo'", "Keywords it accepts: render_mode, g, max_episode_steps"],
        ),
        (["--eval-env-kwargs", "foo:1"], ["`eval_env_kwargs` rejected by Pendulum-v1", "--eval-env-kwargs", "g"]),
        (["--gym-packages", "nosuch"], ["--gym-packages: no module named 'nosuch'"]),
        (["--gym-packages", "sb3_adc.nosuch"], ["--gym-packages: no module named 'sb3_adc.nosuch'"]),
        (["-i", "MISSING"], ["`trained_agent` must be a model file saved by adc", "does not exist", "--trained-agent"]),
        (["--resume", "-tb", "runs"], ["--resume continues a run with its saved settings", "-tb/--tensorboard-log"]),
        (["-optimize", "--track"], ["-optimize does not take --track"]),
        (
            ["--best-model-metric", "success"],
            ["`best_model_metric` 'success' needs episodes that end with info['is_success']", "--best-model-metric"],
        ),
        (["-optimize", "--best-model-metric", "success"], ["-optimize does not take --best-model-metric"]),
    ],
)
def test_bad_input_exits_2_before_any_run_folder(cli, train_args, empty_logs, tmp_path, args, messages):
    args = [str(tmp_path / "missing.zip") if arg == "MISSING" else arg for arg in args]
    status, _, err = cli(*train_args("adc", empty_logs, *args))
    assert status == 2
    for message in messages:
        assert message in err
    assert "Traceback" not in err
    assert list(empty_logs.iterdir()) == []


def test_an_unknown_best_model_metric_is_rejected_by_the_parser(cli, train_args, empty_logs, capsys):
    with pytest.raises(SystemExit) as info:
        cli(*train_args("adc", empty_logs, "--best-model-metric", "accuracy"))
    assert info.value.code == 2
    assert "--best-model-metric: invalid choice: 'accuracy' (choose from 'return', 'success')" in capsys.readouterr().err
    assert list(empty_logs.iterdir()) == []


def test_tensorboard_log_has_adc_diagnostics(cli, train_args, tmp_path):
    event_accumulator = pytest.importorskip("tensorboard.backend.event_processing.event_accumulator")
    tensorboard = tmp_path / "tb"
    assert cli(*train_args("adc", tmp_path / "logs", "-tb", tensorboard))[0] == 0
    # The RL Zoo's layout: {tensorboard_log}/{env_name}/{AlgorithmClass}_{N}.
    (run,) = glob.glob(str(tensorboard / "Pendulum-v1" / "ADC_*"))
    assert os.path.basename(run) == "ADC_1"
    events = event_accumulator.EventAccumulator(run)
    events.Reload()
    scalars = events.Tags()["scalars"]
    for key in ("train/value_mean", "train/advantage_std", "train/critic_loss", "rollout/ep_rew_mean"):
        assert key in scalars, key
    assert all(np.isfinite(event.value) for event in events.Scalars("train/value_mean"))
    saved = TrainSettings.load(str(tmp_path / "logs" / "adc" / "Pendulum-v1_1" / "Pendulum-v1" / "args.yml"))
    assert saved.tensorboard_log == str(tensorboard)


def test_eval_env_kwargs_apply_to_the_evaluation_envs_only(cli, train_args, tmp_path):
    status, _, _ = cli(*train_args("adc", tmp_path / "logs", "-n", 200, "--eval-env-kwargs", "max_episode_steps:20"))
    assert status == 0
    run_dir = tmp_path / "logs" / "adc" / "Pendulum-v1_1"
    with np.load(run_dir / "evaluations.npz") as data:
        assert data["ep_lengths"].tolist() == [[20], [20]]
    assert FinalEvaluation.load(run_dir / "Pendulum-v1" / "final_evaluation.json").lengths == [20, 20]
    training_lengths = np.loadtxt(run_dir / "0.monitor.csv", delimiter=",", skiprows=2, usecols=1)
    assert training_lengths.tolist() == [50, 50, 50, 50]
    assert TrainSettings.of_run(str(run_dir)).eval_env_kwargs == {"max_episode_steps": 20}


def test_periodic_evaluations_leave_what_is_learned_unchanged(cli, train_args, tmp_path):
    """
    A run with periodic evaluations (on other environment settings here) learns the weights of the same run without
    them, so grids that differ only in their evaluations (a validation split, its episodes) train the same models.
    """
    runs = {
        "none": ["--eval-freq", -1],
        "validation": ["--eval-episodes", 2, "--eval-env-kwargs", "max_episode_steps:20"],
    }
    weights = {}
    for name, extra in runs.items():
        status, _, _ = cli(*train_args("adc", tmp_path / name, *extra))
        assert status == 0
        run_dir = tmp_path / name / "adc" / "Pendulum-v1_1"
        assert (run_dir / "evaluations.npz").exists() == (name == "validation")
        weights[name] = ADC.load(run_dir / "Pendulum-v1.zip", device="cpu").policy.state_dict()
    assert weights["none"].keys() == weights["validation"].keys()
    for key, value in weights["none"].items():
        assert th.equal(value, weights["validation"][key]), key


@pytest.mark.parametrize("layout", ["checkpoint", "zoo"])
def test_trained_agent_continues_with_its_weights_and_replay_buffer(cli, train_args, trained_runs, tmp_path, layout):
    checkpoint = trained_runs["adc"] / "rl_model_300_steps.zip"
    if layout == "checkpoint":
        agent = checkpoint
    else:  # the RL Zoo's layout: replay_buffer.pkl beside the model
        (tmp_path / "agent").mkdir()
        agent = tmp_path / "agent" / "model.zip"
        shutil.copy(checkpoint, agent)
        shutil.copy(trained_runs["adc"] / "rl_model_replay_buffer_300_steps.pkl", tmp_path / "agent" / "replay_buffer.pkl")
    # 50 steps: fewer than learning_starts (100), so no gradient step changes the weights loaded.
    status, out, _ = cli(*train_args("adc", tmp_path / "logs", "-n", 50, "-i", agent))
    assert status == 0
    assert f"Continuing the training of {agent}" in out
    # The Zoo's ExperimentManager loads its own layout's replay_buffer.pkl; the engine loads a checkpoint's.
    assert ("Loading replay buffer" if layout == "zoo" else "Loading the replay buffer") in out
    run_dir = tmp_path / "logs" / "adc" / "Pendulum-v1_1"
    model = ADC.load(run_dir / "Pendulum-v1.zip")
    assert model.num_timesteps == 50  # n_timesteps more, counted from 0 as the RL Zoo does
    saved = policy_state(ADC.load(checkpoint))
    for key, value in policy_state(model).items():
        assert th.equal(value, saved[key]), key
    # The replay buffer goes on from the agent's transitions.
    agent_model = ADC.load(checkpoint)
    agent_model.load_replay_buffer(trained_runs["adc"] / "rl_model_replay_buffer_300_steps.pkl")
    model.load_replay_buffer(run_dir / "rl_model_replay_buffer_50_steps.pkl")
    assert model.replay_buffer.size() == agent_model.replay_buffer.size() + 50
    assert agent_model.replay_buffer.size() > 250
    assert TrainSettings.of_run(str(run_dir)).trained_agent == str(agent)


def test_trained_agent_trains_further(cli, train_args, trained_runs, tmp_path):
    agent = trained_runs["ddpg"] / "Pendulum-v1.zip"
    status, out, _ = cli(*train_args("ddpg", tmp_path / "logs", "-n", 200, "-i", agent))
    assert status == 0
    assert "Loading the replay buffer" not in out  # a final model without replay_buffer.pkl beside it
    from sb3_adc.baselines import SplitRateDDPG

    before = policy_state(SplitRateDDPG.load(agent))
    after = policy_state(SplitRateDDPG.load(tmp_path / "logs" / "ddpg" / "Pendulum-v1_1" / "Pendulum-v1.zip"))
    assert any(not th.equal(before[key], after[key]) for key in before)


@pytest.mark.parametrize(
    ("algo", "agent_of", "env", "messages"),
    [
        (
            "adc",
            "ddpg",
            "Pendulum-v1",
            ["must be a model of --algo adc (ADC, policy ADCPolicy)", "the policy ActorAverageTD3Policy"],
        ),
        ("ddpg", "adc", "Pendulum-v1", ["--algo ddpg (SplitRateDDPG, policy ActorAverageTD3Policy)", "the policy ADCPolicy"]),
        ("adc", "adc", "MountainCarContinuous-v0", ["must be a model for the spaces of MountainCarContinuous-v0"]),
    ],
)
def test_trained_agent_of_another_algorithm_or_env_exits_2(
    cli, train_args, trained_runs, empty_logs, algo, agent_of, env, messages
):
    agent = trained_runs[agent_of] / "Pendulum-v1.zip"
    status, _, err = cli(*train_args(algo, empty_logs, "-i", agent, env=env))
    assert status == 2
    for message in [*messages, str(agent), "--trained-agent"]:
        assert message in err
    assert list(empty_logs.iterdir()) == []


def test_damaged_model_files_exit_2(cli, train_args, trained_runs, empty_logs, tmp_path):
    run_dir = tmp_path / "run"
    shutil.copytree(trained_runs["adc"], run_dir)
    final = run_dir / "Pendulum-v1.zip"
    final.write_bytes(final.read_bytes()[:200])
    # sb3-adc enjoy of a damaged model.
    status, _, err = cli("enjoy", "--run-dir", run_dir, "-n", 1)
    assert status == 2
    assert f"Cannot load the ADC model {final}" in err
    # sb3-adc train -i of a damaged model: before the run folder exists.
    status, _, err = cli(*train_args("adc", empty_logs, "-i", final))
    assert status == 2
    assert f"Cannot load the ADC model {final}" in err
    assert list(empty_logs.iterdir()) == []


@pytest.mark.parametrize(
    ("algo", "message"),
    [
        ("adc", "`action_space` must be a continuous gymnasium.spaces.Box with finite bounds, got Discrete(2)"),
        ("ddpg", "`env_id` must be an environment ddpg can act in: The algorithm only supports"),
    ],
)
def test_an_action_space_the_algorithm_cannot_act_in_exits_2(cli, train_args, empty_logs, algo, message):
    status, _, err = cli(*train_args(algo, empty_logs, env="CartPole-v1"))
    assert status == 2
    assert message in err
    assert list(empty_logs.iterdir()) == []


@pytest.mark.parametrize("name", ["args.yml", "config.yml"])
def test_an_alias_bomb_in_a_run_file_is_an_error(cli, trained_runs, tmp_path, name):
    run_dir = tmp_path / "run"
    shutil.copytree(trained_runs["adc"], run_dir)
    (run_dir / "Pendulum-v1" / name).write_text(ALIAS_BOMB)
    for command in (["train", "--resume", run_dir], ["enjoy", "--run-dir", run_dir, "-n", 1]):
        status, _, err = cli(*command)
        assert status == 2
        assert f"{run_dir / 'Pendulum-v1' / name}: file is over a limit of sb3_adc.config.yaml_files" in err
        assert "more than MAX_EXPANDED_VALUES" in err


def test_args_yml_of_an_earlier_version_still_resumes(cli, trained_runs, tmp_path):
    run_dir = tmp_path / "run"
    shutil.copytree(trained_runs["adc"], run_dir)
    args_file = run_dir / "Pendulum-v1" / "args.yml"
    saved = yaml.safe_load(args_file.read_text())
    new_settings = ("eval_env_kwargs", "tensorboard_log", "trained_agent", "track", "wandb_project_name", "wandb_entity")
    args_file.write_text(yaml.safe_dump({key: value for key, value in saved.items() if key not in new_settings}))
    status, out, _ = cli("train", "--resume", run_dir)
    assert status == 0
    assert "has finished" in out
    assert TrainSettings.of_run(str(run_dir)).tensorboard_log is None


def test_track_without_wandb_names_the_extra(cli, train_args, empty_logs, monkeypatch):
    monkeypatch.setitem(sys.modules, "wandb", None)  # as if wandb were not installed
    status, _, err = cli(*train_args("adc", empty_logs, "--track"))
    assert status == 2
    assert "'wandb' (needed by --track) is not installed: it comes with the 'track' extra" in err
    assert 'pip install "sb3-adc[track]"' in err
    assert list(empty_logs.iterdir()) == []


def test_track_logs_to_tensorboard_through_wandb(cli, train_args, tmp_path, monkeypatch):
    pytest.importorskip("wandb")
    pytest.importorskip("tensorboard")
    # Never the network: wandb's disabled mode returns a run that records nothing.
    monkeypatch.setenv("WANDB_MODE", "disabled")
    monkeypatch.setenv("WANDB_DIR", str(tmp_path))
    logs = tmp_path / "logs"
    status, _, _ = cli(*train_args("adc", logs, "-n", 200, "--track", "--wandb-project-name", "tests"))
    assert status == 0
    settings = TrainSettings.of_run(str(logs / "adc" / "Pendulum-v1_1"))
    assert (settings.track, settings.wandb_project_name) == (True, "tests")
    assert settings.tensorboard_log == str(logs / "tensorboard")
    assert glob.glob(str(logs / "tensorboard" / "Pendulum-v1" / "ADC_1" / "events.out.tfevents.*"))
