"""``sb3-adc train`` end to end on tiny budgets: the log layout, the final evaluation, errors, resume."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
import yaml
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback

from sb3_adc import ADC
from sb3_adc.baselines import DuelingDQNPolicy, SplitRateDDPG, VanillaActorCritic
from sb3_adc.cli import build_parser
from sb3_adc.config import CALLBACKS
from sb3_adc.experiment import FinalEvaluation


def evaluations(run_dir):
    with np.load(os.path.join(run_dir, "evaluations.npz")) as data:
        return list(data["timesteps"]), data["results"]


def monitor(run_dir):
    return pd.read_csv(os.path.join(run_dir, "0.monitor.csv"), skiprows=1)


def test_train_writes_the_zoo_layout_and_prints_the_final_evaluation(cli, train_args, tmp_path):
    status, out, _ = cli(*train_args("adc", tmp_path / "logs"))
    assert status == 0
    run_dir = tmp_path / "logs" / "adc" / "Pendulum-v1_1"
    for name in ("Pendulum-v1.zip", "best_model.zip", "evaluations.npz", "0.monitor.csv", "rl_model_300_steps.zip"):
        assert (run_dir / name).is_file(), name
    assert (run_dir / "rl_model_replay_buffer_300_steps.pkl").is_file()
    # Two checkpoints kept (200 and 300), the one at 100 pruned.
    checkpoints = sorted(path.name for path in run_dir.glob("rl_model_[0-9]*_steps.zip"))
    assert checkpoints == ["rl_model_200_steps.zip", "rl_model_300_steps.zip"]
    steps, results = evaluations(run_dir)
    assert steps == [100, 200, 300]
    assert results.shape == (3, 1)
    episodes = monitor(run_dir)
    assert list(episodes["l"]) == [50] * 6
    assert list(episodes["total_steps"]) == [50, 100, 150, 200, 250, 300]
    config = yaml.safe_load((run_dir / "Pendulum-v1" / "config.yml").read_text())
    assert config["n_timesteps"] == 300
    assert config["epsilon_decay_steps"] == 150
    assert config["policy_kwargs"] == "dict(net_arch=[8], value_net_arch=[4])"
    final = FinalEvaluation.load(run_dir / "Pendulum-v1" / "final_evaluation.json")
    assert (final.timesteps, len(final.returns)) == (300, 2)
    assert f"mean return {final.mean_return:.2f} +/- {final.std_return:.2f} over 2 deterministic episodes" in out
    # Pendulum reports no is_success: no success rate, and the file is what it was before success rates.
    assert final.successes is None
    assert final.success_rate is None
    assert "success" not in (run_dir / "Pendulum-v1" / "final_evaluation.json").read_text()
    assert "success rate" not in out
    model = ADC.load(run_dir / "Pendulum-v1.zip")
    assert model.num_timesteps == 300
    assert model.policy.n_intervals == 10


def test_runs_are_numbered_and_the_seed_is_reproducible(cli, train_args, tmp_path):
    logs = tmp_path / "logs"
    assert cli(*train_args("ddpg", logs, "-n", 200, seed=4))[0] == 0
    assert cli(*train_args("ddpg", logs, "-n", 200, seed=4))[0] == 0
    first, second = logs / "ddpg" / "Pendulum-v1_1", logs / "ddpg" / "Pendulum-v1_2"
    assert evaluations(first)[1].tolist() == evaluations(second)[1].tolist()
    pd.testing.assert_frame_equal(monitor(first)[["r", "l"]], monitor(second)[["r", "l"]])
    assert isinstance(SplitRateDDPG.load(first / "Pendulum-v1.zip"), SplitRateDDPG)


def test_dqn_trains_a_dueling_network_over_discretized_actions(cli, train_args, tmp_path):
    status, out, _ = cli(*train_args("dqn", tmp_path / "logs", "-n", 200))
    assert status == 0
    model = DQN.load(tmp_path / "logs" / "dqn" / "Pendulum-v1_1" / "Pendulum-v1.zip")
    assert isinstance(model.policy, DuelingDQNPolicy)
    assert model.action_space.n == 25
    assert "Final evaluation of dqn on Pendulum-v1" in out


def test_vanilla_actor_critic_and_overrides(cli, train_args, tmp_path):
    args = train_args("vanilla_ac", tmp_path / "logs", "-n", 200, "-params", "learning_rate:lin_0.002", "gamma:0.5")
    assert cli(*args)[0] == 0
    run_dir = tmp_path / "logs" / "vanilla_ac" / "Pendulum-v1_1"
    config = yaml.safe_load((run_dir / "Pendulum-v1" / "config.yml").read_text())
    assert (config["learning_rate"], config["gamma"]) == ("lin_0.002", 0.5)
    model = VanillaActorCritic.load(run_dir / "Pendulum-v1.zip")
    assert (model.buffer_size, model.gamma) == (1, 0.5)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--env", "Pendulum-v9"], "unknown environment id 'Pendulum-v9'; closest registered ids: Pendulum-v1"),
        (["-params", "learnig_rate:0.1"], "`learnig_rate`: unknown key for adc (ADC); accepted keys:"),
        (["-params", "gamma:high"], "`gamma`: expected a number >= 0.0, <= 1.0, got 'high'"),
        (["-params", "actor_average_tau:1"], "`actor_average_tau` must be a number >= 0 and < 1"),
        (["-params", "policy_kwargs:dict(a=__import__('os'))"], "function calls are not allowed"),
        (["--env-kwargs", "g"], "overrides must be written key:value"),
        (["-conf", "/nonexistent.yml"], "/nonexistent.yml: hyperparameter file not found"),
        (["--env", "MountainCarContinuous-v0", "-conf", "NO_DEFAULT"], "no entry for environment 'MountainCarContinuous-v0'"),
        (["--algo", None], "--algo and --env are required"),
        (["--algo", None, "--resume"], "--resume without RUN_DIR needs --algo and --env"),
        (["--resume", "/nonexistent/run"], "/nonexistent/run holds no sb3-adc run"),
    ],
)
def test_bad_input_is_a_clear_error(cli, tiny_conf, tmp_path, args, message):
    no_default = tmp_path / "no_default.yml"
    no_default.write_text("Pendulum-v1: {n_timesteps: 10, policy: MlpPolicy}\n")
    options = {"--algo": "adc", "--env": "Pendulum-v1", "-conf": str(tiny_conf / "adc.yml")}
    extra = []
    for index in range(0, len(args), 2):
        key, value = args[index], args[index + 1] if index + 1 < len(args) else None
        if key in options:
            options[key] = str(no_default) if value == "NO_DEFAULT" else value
        else:
            extra += [key] if value is None else [key, value]
    command = ["train", "-f", tmp_path / "logs", "-n", 10]
    command += [item for key, value in options.items() if value is not None for item in (key, value)]
    status, _, err = cli(*command, *extra)
    assert status == 2
    assert message in err
    assert not (tmp_path / "logs").exists()


def test_unknown_algo_is_rejected_by_the_parser(capsys):
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["train", "--algo", "ppo3", "--env", "Pendulum-v1"])
    assert info.value.code == 2
    assert "invalid choice: 'ppo3'" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["train", "enjoy", "benchmark", "plot"])
def test_every_subcommand_has_help(capsys, command):
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args([command, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert f"usage: sb3-adc {command}" in out
    assert "examples:" in out or "example:" in out


class InterruptAt(BaseCallback):
    """Raise KeyboardInterrupt (as Ctrl-C) when training reaches a timestep."""

    def __init__(self, at):
        super().__init__()
        self.at = at

    def _on_step(self):
        if self.num_timesteps == self.at:
            raise KeyboardInterrupt
        return True


@pytest.fixture
def interrupting_callback():
    CALLBACKS.add("tests.InterruptAt", InterruptAt)
    yield
    CALLBACKS.remove("tests.InterruptAt")


def test_ctrl_c_saves_a_checkpoint_and_resume_loses_no_finished_work(cli, train_args, tmp_path, interrupting_callback):
    logs = tmp_path / "logs"
    args = train_args("adc", logs, "-n", 400, "--save-freq", 1000, "-params", "callback:{tests.InterruptAt: {at: 230}}")
    status, out, _ = cli(*args)
    assert status == 130
    run_dir = logs / "adc" / "Pendulum-v1_1"
    assert "Continue with: sb3-adc train --resume" in out
    assert (run_dir / "rl_model_230_steps.zip").is_file()
    assert (run_dir / "rl_model_replay_buffer_230_steps.pkl").is_file()
    assert not (run_dir / "Pendulum-v1.zip").exists()
    steps_before, results_before = evaluations(run_dir)
    assert steps_before == [100, 200]
    episodes_before = monitor(run_dir)
    assert list(episodes_before["total_steps"]) == [50, 100, 150, 200]
    interrupted = ADC.load(run_dir / "rl_model_230_steps.zip")
    noise_calls = interrupted.action_noise.n_calls

    status, out, _ = cli("train", "--algo", "adc", "--env", "Pendulum-v1", "-f", logs, "--resume")
    assert status == 0
    assert "Resuming" in out
    assert "from timestep 230 of 400" in out
    steps, results = evaluations(run_dir)
    assert steps == [100, 200, 300, 400]
    np.testing.assert_array_equal(results[:2], results_before)
    episodes = monitor(run_dir)
    # The episodes finished before the interruption are kept; the one in progress restarts after the checkpoint.
    pd.testing.assert_frame_equal(episodes.iloc[:4][["r", "l"]], episodes_before[["r", "l"]])
    assert list(episodes["total_steps"])[4:] == [280, 330, 380]
    final = ADC.load(run_dir / "Pendulum-v1.zip")
    assert final.num_timesteps == 400
    # The exploration noise continued from where it was, with the replay buffer.
    assert final.action_noise.n_calls == noise_calls + 170
    final.load_replay_buffer(run_dir / "rl_model_replay_buffer_400_steps.pkl")
    # Every transition but the one of the step Ctrl-C interrupted (SB3 stores it after the callbacks).
    assert final.replay_buffer.size() == 400 - 1

    status, out, _ = cli("train", "--resume", run_dir)
    assert status == 0
    assert "has finished" in out


def test_resume_after_the_process_is_killed(tmp_path, tiny_conf):
    """A run killed without warning (SIGKILL) resumes from its last periodic checkpoint."""
    logs = tmp_path / "logs"
    command = [sys.executable, "-m", "sb3_adc", "train", "--algo", "adc", "--env", "Pendulum-v1", "-f", str(logs)]
    command += ["-conf", str(tiny_conf / "adc.yml"), "-n", "100000", "--eval-freq", "100", "--eval-episodes", "1"]
    command += ["--seed", "1", "--no-progress-bar"]
    # From another working directory, as a user would.
    process = subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    run_dir = logs / "adc" / "Pendulum-v1_1"
    try:
        deadline = time.monotonic() + 120
        while not (run_dir / "rl_model_300_steps.zip").exists():
            assert process.poll() is None, process.stderr.read().decode()
            assert time.monotonic() < deadline, "no checkpoint after 120 s"
            time.sleep(0.2)
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()
    checkpoint = max(int(path.name.split("_")[2]) for path in run_dir.glob("rl_model_[0-9]*_steps.zip"))
    from sb3_adc.experiment import resume

    result = resume(str(run_dir), n_timesteps=checkpoint + 200, progress_bar=False)
    assert result.resumed_from == checkpoint
    steps, _ = evaluations(run_dir)
    assert steps == list(range(100, checkpoint + 201, 100))
    totals = list(monitor(run_dir)["total_steps"])
    assert totals == sorted(totals)
    assert len(totals) == len(set(totals))
    assert result.final_evaluation.timesteps == checkpoint + 200


def test_shipped_hyperparameters_from_any_working_directory(cli, tmp_path, monkeypatch):
    """Without -conf, the YAML shipped inside the package is used, wherever the command runs."""
    monkeypatch.chdir(tmp_path)
    args = ["--algo", "adc", "--env", "sb3_adc/NoisyPendulum-v1", "-n", 150, "--seed", 0, "--eval-freq", -1]
    status, out, _ = cli("train", *args, "--final-eval-episodes", 1)
    assert status == 0
    assert "adc.yml [sb3_adc/NoisyPendulum-v1]" in out
    run_dir = tmp_path / "logs" / "adc" / "sb3_adc-NoisyPendulum-v1_1"
    assert (run_dir / "sb3_adc-NoisyPendulum-v1.zip").is_file()
    config = yaml.safe_load((run_dir / "sb3_adc-NoisyPendulum-v1" / "config.yml").read_text())
    assert config["n_timesteps"] == 150
    assert "Final evaluation of adc on sb3_adc/NoisyPendulum-v1 (seed 0, 150 steps)" in out
    assert not (run_dir / "evaluations.npz").exists()


def test_console_script_and_python_m(tmp_path):
    version = subprocess.run(
        [sys.executable, "-m", "sb3_adc", "--version"], cwd=tmp_path, capture_output=True, text=True, check=True
    )
    assert version.stdout.startswith("sb3-adc ")
    script = os.path.join(os.path.dirname(sys.executable), "sb3-adc")
    if not os.path.isfile(script):
        pytest.skip("the sb3-adc console script is not installed next to this Python")
    help_text = subprocess.run([script, "benchmark", "--help"], cwd=tmp_path, capture_output=True, text=True, check=True)
    assert "--backend {local,ray}" in help_text.stdout
