"""Fault injection: damage the files of an interrupted run on disk, then resume it; and crashes while writing."""

import os
import re
import shutil
import warnings

import numpy as np
import pandas as pd
import pytest
from stable_baselines3 import TD3
from stable_baselines3.common.buffers import NStepReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback

import sb3_adc.experiment.restore as restore
from sb3_adc import ADC
from sb3_adc.common.model_files import LOADED_N_STEP_WARNING, loading_model
from sb3_adc.experiment import RunInterrupted, resume, train
from sb3_adc.experiment.callbacks import EvaluationHistory
from sb3_adc.experiment.layout import DamagedFileError, RunLayout
from sb3_adc.experiment.restore import checkpoint_damage


class InterruptAt(BaseCallback):
    """Raise KeyboardInterrupt (as Ctrl-C) when training reaches a timestep."""

    def __init__(self, at: int):
        super().__init__()
        self.at = at

    def _on_step(self) -> bool:
        if self.num_timesteps == self.at:
            raise KeyboardInterrupt
        return True


@pytest.fixture(scope="module")
def interrupted(tmp_path_factory, tiny_settings):
    """A run interrupted at timestep 250: checkpoints at 100, 200 and 250, evaluations at 100 and 200."""
    folder = tmp_path_factory.mktemp("interrupted")
    with pytest.raises(RunInterrupted):
        train(tiny_settings(folder), callbacks=[InterruptAt(250)])
    return folder / "logs" / "adc" / "Pendulum-v1_1"


@pytest.fixture
def run_dir(interrupted, tmp_path):
    """A copy of the interrupted run, to damage."""
    copy = tmp_path / "run"
    shutil.copytree(interrupted, copy)
    return copy


def truncate(path, keep=0.5):
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def evaluation_steps(run_dir):
    return EvaluationHistory.load(str(run_dir / "evaluations.npz")).timesteps


def test_the_interrupted_run_is_intact(interrupted):
    layout = RunLayout(str(interrupted), "Pendulum-v1")
    assert [checkpoint.timesteps for checkpoint in layout.checkpoints()] == [100, 200, 250]
    assert all(checkpoint_damage(checkpoint) is None for checkpoint in layout.checkpoints())
    assert evaluation_steps(interrupted) == [100, 200]
    assert not list(interrupted.glob("*.partial*"))
    # The periodic checkpoints can be continued exactly; the one of Ctrl-C, taken wherever it fell, cannot.
    assert [os.path.isfile(checkpoint.continuation) for checkpoint in layout.checkpoints()] == [True, True, False]


def without_manifests(run_dir):
    """The run as written before checkpoints had manifests: only reading the files tells whether they are intact."""
    for checkpoint in RunLayout(str(run_dir), "Pendulum-v1").checkpoints():
        os.remove(checkpoint.manifest)


@pytest.mark.parametrize(
    ("damaged", "reason", "manifest"),
    [
        ("rl_model_250_steps.zip", "rl_model_250_steps.zip does not match its manifest (size differs)", True),
        ("rl_model_replay_buffer_250_steps.pkl", "rl_model_replay_buffer_250_steps.pkl does not match its", True),
        # Cut in half, the zip may still open (on the zip torch writes inside it) but lacks the model's members.
        ("rl_model_250_steps.zip", "rl_model_250_steps.zip ", False),
        ("rl_model_replay_buffer_250_steps.pkl", "rl_model_replay_buffer_250_steps.pkl does not unpickle", False),
    ],
)
def test_resume_falls_back_to_the_newest_intact_checkpoint(run_dir, capsys, damaged, reason, manifest):
    if not manifest:
        without_manifests(run_dir)
    truncate(run_dir / damaged)
    result = resume(str(run_dir))
    out = capsys.readouterr().out
    assert f"The checkpoint at timestep 250 is damaged ({reason}" in out
    assert "from timestep 200 of 300" in out
    assert result.resumed_from == 200
    # The damaged checkpoint is set aside, not deleted; the run finished from the one before it.
    assert (run_dir / (damaged + ".damaged")).is_file()
    assert ADC.load(run_dir / "Pendulum-v1.zip").num_timesteps == 300
    assert evaluation_steps(run_dir) == [100, 200, 300]
    episodes = pd.read_csv(run_dir / "0.monitor.csv", skiprows=1)
    assert list(episodes["total_steps"]) == [50, 100, 150, 200, 250, 300]


def test_a_damaged_continuation_makes_its_checkpoint_damaged(run_dir, capsys):
    RunLayout(str(run_dir), "Pendulum-v1").checkpoint(250).remove()
    truncate(run_dir / "rl_model_continuation_200_steps.pkl")
    result = resume(str(run_dir))
    out = capsys.readouterr().out
    assert "The checkpoint at timestep 200 is damaged (rl_model_continuation_200_steps.pkl does not match its" in out
    assert result.resumed_from == 100
    assert (run_dir / "rl_model_continuation_200_steps.pkl.damaged").is_file()
    assert (run_dir / "rl_model_200_steps.zip.damaged").is_file()
    assert (run_dir / "rl_model_manifest_200_steps.json.damaged").is_file()


@pytest.mark.parametrize("manifest", [True, False])
def test_a_corrupted_member_of_a_checkpoint_zip_is_found(run_dir, manifest, monkeypatch):
    # Same length, one flipped byte inside a member: the manifest's SHA-256 sees it, and without one the CRC check.
    if manifest:

        def no_unpickling(*args, **kwargs):
            raise AssertionError("the manifest's check unpickled a file")

        for name in ("restricted_load", "safe_objects", "load_from_pkl"):
            monkeypatch.setattr(restore, name, no_unpickling)
    else:
        without_manifests(run_dir)
    path = run_dir / "rl_model_250_steps.zip"
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF
    path.write_bytes(bytes(data))
    layout = RunLayout(str(run_dir), "Pendulum-v1")
    damage = checkpoint_damage(layout.checkpoint(250))
    assert damage is not None
    assert "rl_model_250_steps.zip" in damage
    assert (damage == "rl_model_250_steps.zip does not match its manifest (SHA-256 differs)") == manifest
    assert checkpoint_damage(layout.checkpoint(200)) is None


def test_no_intact_checkpoint_starts_the_run_again(run_dir, capsys):
    for steps in (100, 200, 250):
        truncate(run_dir / f"rl_model_{steps}_steps.zip", keep=0.1)
    result = resume(str(run_dir))
    assert "No intact checkpoint is left: the run starts again from timestep 0." in capsys.readouterr().out
    assert result.resumed_from is None
    assert evaluation_steps(run_dir) == [100, 200, 300]


def test_a_damaged_evaluation_history_restarts_after_the_checkpoint(run_dir, capsys):
    truncate(run_dir / "evaluations.npz")
    with pytest.raises(DamagedFileError, match=r"evaluations\.npz is damaged"):
        EvaluationHistory.load(str(run_dir / "evaluations.npz"))
    resume(str(run_dir))
    out = capsys.readouterr().out
    assert "evaluations.npz is damaged" in out
    assert "the evaluations before timestep 250 are lost" in out
    assert "from timestep 250 of 300" in out
    assert evaluation_steps(run_dir) == [300]


def test_a_partial_last_monitor_line_is_dropped(run_dir):
    monitor = run_dir / "0.monitor.csv"
    with open(monitor, "a", encoding="utf-8", newline="") as stream:
        stream.write("-123.4,5")  # killed while writing an episode
    resume(str(run_dir))
    episodes = pd.read_csv(monitor, skiprows=1)
    assert not episodes.isna().any().any()
    assert list(episodes["total_steps"]) == [50, 100, 150, 200, 250, 300]
    assert -123.4 not in list(episodes["r"])


def test_a_crash_while_writing_evaluations_keeps_the_previous_file(tmp_path, monkeypatch, tiny_settings):
    """SB3's EvalCallback writes evaluations.npz in place; a crash in the second write must not damage it."""
    real_savez = np.savez
    calls = []

    def crash_on_second_write(file, *args, **kwargs):
        calls.append(file)
        if len(calls) == 2:
            # Half a file where np.savez writes (it adds .npz to a path without it), then the crash.
            target = file if str(file).endswith(".npz") else f"{file}.npz"
            with open(target, "wb") as stream:
                stream.write(b"PK\x03\x04 half a zip")
            raise OSError("no space left on device")
        return real_savez(file, *args, **kwargs)

    monkeypatch.setattr(np, "savez", crash_on_second_write)
    with pytest.raises(OSError, match="no space left"):
        train(tiny_settings(tmp_path, save_freq=1000))
    run_dir = tmp_path / "logs" / "adc" / "Pendulum-v1_1"
    monkeypatch.undo()
    assert evaluation_steps(run_dir) == [100]
    assert not list(run_dir.glob("*.partial*"))


TINY_TD3_N_STEP = """\
default:
  n_timesteps: 200
  policy: MlpPolicy
  learning_starts: 50
  batch_size: 16
  buffer_size: 1000
  gamma: 0.9
  n_steps: 3
  policy_kwargs: "dict(net_arch=[8])"
  env_kwargs: {max_episode_steps: 50}
"""


def test_a_resumed_n_step_run_keeps_its_returns_without_sb3s_warning(tmp_path, tiny_settings):
    # The checkpoint's model is loaded with its NStepReplayBuffer: SB3 warns that n_steps "is ignored"; it is not.
    conf = tmp_path / "td3.yml"
    conf.write_text(TINY_TD3_N_STEP)
    with pytest.raises(RunInterrupted):
        train(tiny_settings(tmp_path, algo="td3", conf_file=str(conf)), callbacks=[InterruptAt(150)])
    run_dir = tmp_path / "logs" / "td3" / "Pendulum-v1_1"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = resume(str(run_dir))
    assert result.resumed_from == 150
    assert not [w for w in caught if re.search(LOADED_N_STEP_WARNING, str(w.message))]
    with loading_model():  # SB3's own TD3.load warns likewise
        model = TD3.load(run_dir / "Pendulum-v1.zip")
    assert model.num_timesteps == 200
    assert model.replay_buffer_class is NStepReplayBuffer
    assert model.replay_buffer_kwargs == {"n_steps": 3, "gamma": 0.9}
