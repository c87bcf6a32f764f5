"""Runs started at the same time into one log folder each claim their own run folder; a run writes nothing outside
it; atomic writes."""

import os
import tempfile
import threading

import pytest

import sb3_adc.experiment.layout as layout_module
from sb3_adc.common.atomic import atomic_path, write_atomically
from sb3_adc.experiment import TrainSettings, train
from sb3_adc.experiment.layout import new_run_dir


@pytest.fixture
def ddpg_settings(tmp_path, tiny_settings):
    """``make(**changes)``: a tiny DDPG run on Pendulum-v1 logging under ``tmp_path/logs``, without evaluations or
    checkpoints."""

    def make(**changes) -> TrainSettings:
        return tiny_settings(tmp_path, "ddpg", algo="ddpg", seed=0, eval_freq=0, save_freq=0, keep_checkpoints=2, **changes)

    return make


def test_racing_threads_each_claim_a_different_run_folder(tmp_path):
    n_threads = 8
    barrier = threading.Barrier(n_threads)
    claimed = []

    def claim():
        barrier.wait()
        claimed.append(new_run_dir(str(tmp_path), "adc", "Pendulum-v1"))

    threads = [threading.Thread(target=claim) for _ in range(n_threads)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(claimed, key=lambda path: int(path.rsplit("_", 1)[1])) == [
        str(tmp_path / "adc" / f"Pendulum-v1_{run_id}") for run_id in range(1, n_threads + 1)
    ]
    assert all(os.path.isdir(path) for path in claimed)


def test_a_run_that_loses_the_race_trains_in_the_next_folder_and_says_which(tmp_path, monkeypatch, capsys, ddpg_settings):
    settings = ddpg_settings()
    # Another run claims Pendulum-v1_1 between this run's listing of the folder and its claim.
    winner = tmp_path / "logs" / "ddpg" / "Pendulum-v1_1"
    real_run_ids = layout_module.run_ids
    listings = []

    def stale_run_ids(*args):
        listings.append(args)
        if len(listings) == 1:
            (winner / "Pendulum-v1").mkdir(parents=True)
            return []
        return real_run_ids(*args)

    monkeypatch.setattr(layout_module, "run_ids", stale_run_ids)
    result = train(settings)
    assert result.run_dir == str(tmp_path / "logs" / "ddpg" / "Pendulum-v1_2")
    assert f"in {result.run_dir}" in capsys.readouterr().out
    # The other run's folder is left alone.
    assert os.listdir(winner) == ["Pendulum-v1"]
    assert os.listdir(winner / "Pendulum-v1") == []


@pytest.mark.parametrize("verbose", [0, 1])
def test_a_run_writes_nothing_in_the_temporary_directory(tmp_path, monkeypatch, capsys, verbose, ddpg_settings):
    """SB3's default logger makes an empty ``SB3-<date>`` folder in the temporary directory for every model."""
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    # Four episodes of 50 steps: SB3 logs every fourth episode.
    settings = ddpg_settings(verbose=verbose, n_timesteps=200)
    train(settings)
    assert list(scratch.glob("SB3-*")) == []
    # The training logs still go to the console when asked for.
    assert ("actor_loss" in capsys.readouterr().out) == bool(verbose)


def test_a_failed_atomic_write_keeps_the_previous_file(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text("old\n")

    def crash(stream):
        stream.write("half of the new")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        write_atomically(path, crash)
    assert path.read_text() == "old\n"
    assert os.listdir(tmp_path) == ["table.csv"]
    write_atomically(path, lambda stream: stream.write("new\n"))
    assert path.read_text() == "new\n"


def test_atomic_path_keeps_the_extension_for_writers_that_add_one(tmp_path):
    with atomic_path(tmp_path / "model.zip") as temporary:
        assert temporary == str(tmp_path / "model.partial.zip")
        with open(temporary, "wb") as stream:
            stream.write(b"zip")
    assert (tmp_path / "model.zip").read_bytes() == b"zip"
    assert not (tmp_path / "model.partial.zip").exists()
