"""Run folders, run ids, checkpoints and monitor trimming of the RL-Zoo log layout."""

import pytest

from sb3_adc.experiment.layout import RunLayout, env_name, latest_run_dir, new_run_dir, run_ids
from sb3_adc.experiment.monitor_files import read_monitor, truncate_monitor
from sb3_adc.experiment.settings import TrainSettings

HEADER = '#{"t_start": 0.0, "env_id": "Pendulum-v1"}\n'


def test_run_ids_follow_the_zoo(tmp_path):
    assert env_name("sb3_adc/NoisyPendulum-v1") == "sb3_adc-NoisyPendulum-v1"
    folder = tmp_path / "adc"
    for name in ("Pendulum-v1_1", "Pendulum-v1_7", "Pendulum-v1_x", "Pendulum-v1_seed3", "Pendulum-v2_9"):
        (folder / name).mkdir(parents=True)
    (folder / "Pendulum-v1_12").write_text("a file, not a run")
    assert run_ids(str(tmp_path), "adc", "Pendulum-v1") == [1, 7]
    assert latest_run_dir(str(tmp_path), "adc", "Pendulum-v1") == str(folder / "Pendulum-v1_7")
    # The new run's folder is created (claimed): the next new run gets the id after it.
    assert new_run_dir(str(tmp_path), "adc", "Pendulum-v1") == str(folder / "Pendulum-v1_8")
    assert (folder / "Pendulum-v1_8").is_dir()
    assert new_run_dir(str(tmp_path), "adc", "Pendulum-v1") == str(folder / "Pendulum-v1_9")
    assert latest_run_dir(str(tmp_path), "ddpg", "Pendulum-v1") is None
    assert new_run_dir(str(tmp_path), "ddpg", "sb3_adc/NoisyPendulum-v1").endswith("ddpg/sb3_adc-NoisyPendulum-v1_1")


def test_checkpoints_are_listed_by_timestep(tmp_path):
    layout = RunLayout(str(tmp_path), "Pendulum-v1")
    for steps in (900, 100, 1000):
        (tmp_path / f"rl_model_{steps}_steps.zip").write_bytes(b"")
    (tmp_path / "rl_model_replay_buffer_1000_steps.pkl").write_bytes(b"")
    (tmp_path / "rl_model_200_steps.zip.partial").write_bytes(b"")
    assert [checkpoint.timesteps for checkpoint in layout.checkpoints()] == [100, 900, 1000]
    assert layout.checkpoints()[-1].replay_buffer == str(tmp_path / "rl_model_replay_buffer_1000_steps.pkl")
    assert not layout.is_finished()


def test_truncate_monitor_keeps_the_episodes_before_the_checkpoint(tmp_path):
    path = tmp_path / "0.monitor.csv"
    path.write_text(HEADER + "r,l,t,total_steps\n-1.0,50,0.1,50\n-2.0,50,0.2,100\n-3.0,50,0.3,150\n")
    assert truncate_monitor(str(path), 120) == 1
    assert path.read_text().startswith(HEADER)
    assert read_monitor(str(path))["total_steps"].tolist() == [50, 100]
    # A monitor file without the step column (not written by sb3-adc) is left alone.
    other = tmp_path / "1.monitor.csv"
    other.write_text(HEADER + "r,l,t\n-1.0,50,0.1\n")
    assert truncate_monitor(str(other), 0) == 0
    assert len(read_monitor(str(other))) == 1


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"eval_episodes": 0}, "`eval_episodes` must be an integer >= 1"),
        ({"keep_checkpoints": 0}, "`keep_checkpoints` must be an integer >= 1"),
        ({"vec_env": "forkserver"}, "`vec_env` must be 'dummy' or 'subproc'"),
    ],
)
def test_invalid_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TrainSettings(algo="adc", env_id="Pendulum-v1", **kwargs)


def test_settings_round_trip_and_intervals(tmp_path):
    settings = TrainSettings(algo="adc", env_id="Pendulum-v1", seed=3, overrides={"gamma": 0.9}, eval_freq=None, save_freq=0)
    settings.save(str(tmp_path / "args.yml"))
    assert TrainSettings.load(str(tmp_path / "args.yml")) == settings
    assert settings.evaluation_interval(20_000) == 1000
    assert settings.checkpoint_interval(20_000) == 0
    (tmp_path / "bad.yml").write_text("algo: adc\nenv_id: Pendulum-v1\nlearning_rate: 3\n")
    with pytest.raises(ValueError, match="does not hold sb3-adc run settings"):
        TrainSettings.load(str(tmp_path / "bad.yml"))


def test_checkpoints_are_read_under_the_names_sb3_checkpoint_callback_writes(tmp_path):
    """CheckpointSaver writes with SB3's CheckpointCallback names; the layout must find them under the same names."""
    from sb3_adc.experiment.callbacks import CheckpointSaver

    layout = RunLayout(str(tmp_path), "Pendulum-v1")
    saver = CheckpointSaver(layout, every=100, keep=2)
    saver.num_timesteps = 300
    checkpoint = layout.checkpoint(300)
    assert saver._checkpoint_path(extension="zip") == checkpoint.model
    assert saver._checkpoint_path("replay_buffer_", extension="pkl") == checkpoint.replay_buffer
    assert saver._checkpoint_path("vecnormalize_", extension="pkl") == checkpoint.vecnormalize
    (tmp_path / "rl_model_300_steps.zip").write_bytes(b"")
    assert [found.timesteps for found in layout.checkpoints()] == [300]
