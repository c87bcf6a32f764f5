"""
One writer per run folder and per benchmark folder: a second ``sb3-adc train --resume`` of a run in progress, or a
second ``sb3-adc benchmark`` on a folder in use, fails at once (exit status 2, naming the folder) without writing
anything, and a process killed with SIGKILL leaves nothing locked behind.

The first process of each test is ``sb3-adc`` with a gate: its run waits at timestep 200 until the test opens it, so
the second process always meets a run in progress, however slow the machine.
"""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pandas as pd
import pytest
import yaml

from sb3_adc.cli import main
from sb3_adc.experiment import FinalEvaluation, RunLayout, RunLocked, TrainSettings, resume, train
from sb3_adc.experiment.invocations import INVOCATIONS_JSON
from sb3_adc.experiment.layout import LOCK_FILE, FolderLock

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL and flock: POSIX")

TINY_ADC = """
    Pendulum-v1:
      n_timesteps: 300
      policy: MlpPolicy
      learning_starts: 100
      batch_size: 16
      buffer_size: 1000
      noise_type: epsilon-normal
      noise_std: 0.1
      n_intervals: 10
      policy_kwargs: "dict(net_arch=[8], value_net_arch=[4])"
      env_kwargs: {max_episode_steps: 50}
    """

#: ``sb3-adc`` whose runs wait at timestep 200 (after touching WAITING) until the file GO exists.
GATED_CLI = """
import os, sys, time
from stable_baselines3.common.callbacks import BaseCallback
from sb3_adc.cli import main
from sb3_adc.experiment.manager import RunManager

waiting, go = sys.argv[1], sys.argv[2]


class Gate(BaseCallback):
    def _on_step(self):
        if self.num_timesteps == 200:
            open(waiting, "w").close()
            deadline = time.monotonic() + 300
            while not os.path.exists(go) and time.monotonic() < deadline:
                time.sleep(0.05)
        return True


create_callbacks = RunManager.create_callbacks


def gated(self):
    create_callbacks(self)
    self.callbacks.append(Gate())


RunManager.create_callbacks = gated
raise SystemExit(main(sys.argv[3:]))
"""


@pytest.fixture
def conf(tmp_path):
    path = tmp_path / "adc.yml"
    path.write_text(textwrap.dedent(TINY_ADC))
    return path


def train_args(conf, logs):
    return [
        *("train", "--algo", "adc", "--env", "Pendulum-v1", "-conf", str(conf), "-f", str(logs), "--seed", "0"),
        *("--eval-freq", "100", "--eval-episodes", "1", "--final-eval-episodes", "2", "--no-progress-bar"),
    ]


def benchmark_args(conf, folder):
    return [
        *("benchmark", "--algos", "adc", "--envs", "Pendulum-v1", "--seeds", "0", "-f", str(folder)),
        *("--conf-folder", str(conf.parent), "-n", "300", "--eval-freq", "100", "--eval-episodes", "1"),
        *("--final-eval-episodes", "2", "--workers", "1"),
    ]


class Gated:
    """A gated ``sb3-adc`` process (:data:`GATED_CLI`), its output in files."""

    def __init__(self, tmp_path, args):
        self.waiting, self.go = tmp_path / "waiting", tmp_path / "go"
        self.out, self.err = tmp_path / "first.out", tmp_path / "first.err"
        command = [sys.executable, "-c", GATED_CLI, str(self.waiting), str(self.go), *args]
        with open(self.out, "wb") as out, open(self.err, "wb") as err:
            self.process = subprocess.Popen(command, cwd=tmp_path, stdout=out, stderr=err)

    def wait_at_the_gate(self):
        deadline = time.monotonic() + 180
        while not self.waiting.exists():
            assert self.process.poll() is None, self.err.read_text()
            assert time.monotonic() < deadline, "the first process did not reach timestep 200 in 180 s"
            time.sleep(0.1)

    def open_gate(self):
        self.go.touch()
        return self.process.wait(timeout=180)

    def kill(self):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGKILL)
        self.process.wait()


def sb3_adc(*args, cwd):
    return subprocess.run([sys.executable, "-m", "sb3_adc", *args], cwd=cwd, capture_output=True, text=True, timeout=180)


def test_a_second_resume_of_a_run_in_progress_fails_at_once_and_the_first_finishes(tmp_path, conf):
    logs = tmp_path / "logs"
    first = Gated(tmp_path, train_args(conf, logs))
    run_dir = logs / "adc" / "Pendulum-v1_1"
    try:
        first.wait_at_the_gate()
        second = sb3_adc("train", "--resume", str(run_dir), "-n", "2400", cwd=tmp_path)
        assert first.process.poll() is None, "the first process must still be at its gate"
        assert second.returncode == 2, second.stderr
        assert f"{run_dir} is in use" in second.stderr
        assert f"another process (PID {first.process.pid}) is training it" in second.stderr
        assert "Traceback" not in second.stderr
        assert first.open_gate() == 0, first.err.read_text()
    finally:
        first.kill()
    # The first run's files agree: the second changed nothing (the budget of config.yml included).
    config = yaml.safe_load((run_dir / "Pendulum-v1" / "config.yml").read_text())
    assert config["n_timesteps"] == 300
    final = FinalEvaluation.load(run_dir / "Pendulum-v1" / "final_evaluation.json")
    assert final.timesteps == 300
    episodes = pd.read_csv(run_dir / "0.monitor.csv", skiprows=1)
    assert list(episodes["total_steps"]) == [50, 100, 150, 200, 250, 300]
    with np.load(run_dir / "evaluations.npz") as data:
        assert list(data["timesteps"]) == [100, 200, 300]
    assert not list(run_dir.glob("*.partial*"))
    # The lock file stays, released: the run can be resumed (it has finished).
    assert (run_dir / LOCK_FILE).read_text().strip() == str(first.process.pid)
    assert resume(str(run_dir), progress_bar=False).resumed_from == 300


def test_a_run_killed_with_sigkill_can_be_resumed_at_once(tmp_path, conf):
    logs = tmp_path / "logs"
    first = Gated(tmp_path, train_args(conf, logs))
    run_dir = logs / "adc" / "Pendulum-v1_1"
    try:
        first.wait_at_the_gate()
        with pytest.raises(RunLocked, match=f"PID {first.process.pid}"):
            RunLayout(str(run_dir), "Pendulum-v1").lock().acquire()
    finally:
        first.kill()
    assert first.process.returncode == -signal.SIGKILL
    # The OS released the lock with the process: no stale lock to remove by hand.
    with RunLayout(str(run_dir), "Pendulum-v1").lock() as lock:
        assert lock.held
    result = resume(str(run_dir), progress_bar=False)
    assert result.resumed_from == 200
    assert result.final_evaluation.timesteps == 300


def test_a_second_benchmark_on_a_folder_in_use_fails_at_once_and_every_invocation_is_recorded(tmp_path, conf, capsys):
    folder = tmp_path / "bench"
    first = Gated(tmp_path, benchmark_args(conf, folder))
    try:
        first.wait_at_the_gate()
        before = (folder / INVOCATIONS_JSON).read_text()
        second = sb3_adc(*benchmark_args(conf, folder), cwd=tmp_path)
        assert second.returncode == 2, second.stderr
        assert f"{folder} is in use: another process (PID {first.process.pid}) is running a benchmark" in second.stderr
        assert "Traceback" not in second.stderr
        # The second wrote nothing: not its invocation, not a run.
        assert (folder / INVOCATIONS_JSON).read_text() == before
    finally:
        first.kill()  # killed at its gate: its record stays, unfinished
    assert main(benchmark_args(conf, folder)) == 0
    assert "resumed" in capsys.readouterr().out
    with open(folder / INVOCATIONS_JSON, encoding="utf-8") as stream:
        invocations = json.load(stream)
    assert [entry["finished"] for entry in invocations] == [False, True]
    assert [entry["runs"]["resumed"] for entry in invocations] == [0, 1]
    final = pd.read_csv(folder / "final.csv")
    assert list(final["timesteps"]) == [300]


def test_the_run_lock_is_exclusive_within_one_process(tmp_path):
    folder = tmp_path / "run"
    with FolderLock(str(folder)) as lock:
        assert (folder / LOCK_FILE).read_text() == f"{os.getpid()}\n"
        with pytest.raises(RunLocked) as error:
            FolderLock(str(folder)).acquire()
        assert error.value.folder == str(folder)
        assert error.value.pid == os.getpid()
        assert f"{folder} is in use: another process (PID {os.getpid()}) is training it" in str(error.value)
        with pytest.raises(RuntimeError, match="already held"):
            lock.acquire()
    assert not lock.held
    # Released, the file stays and the lock can be taken again.
    assert (folder / LOCK_FILE).is_file()
    with FolderLock(str(folder)) as again:
        assert again.held


def test_train_into_a_locked_run_folder_writes_nothing(tmp_path):
    run_dir = tmp_path / "logs" / "adc" / "Pendulum-v1_seed0"
    settings = TrainSettings(
        algo="adc",
        env_id="Pendulum-v1",
        seed=0,
        n_timesteps=100,
        overrides={"policy_kwargs": {"net_arch": [4]}, "learning_starts": 50, "batch_size": 8},
        log_folder=str(tmp_path / "logs"),
        run_dir=str(run_dir),
        eval_freq=-1,
        final_eval_episodes=1,
        progress_bar=False,
    )
    with RunLayout(str(run_dir), "Pendulum-v1").lock(), pytest.raises(RunLocked, match="is training it"):
        train(settings)
    assert os.listdir(run_dir) == [LOCK_FILE]
