"""
One writer per folder beyond the runs: ``sb3-adc experiment FILE --report`` holds the results folder's lock (the one a
running experiment holds), and a tuning command holds its study folder's lock for its life, so that a second
command on the same study (kept in a journal file) fails at once with exit status 2, while a study kept in a database
stays shared on purpose.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import sb3_adc.experiment.summary as summary
from sb3_adc.cli import main
from sb3_adc.experiment import tuning_trials
from sb3_adc.experiment.layout import FolderLock, RunLocked
from sb3_adc.experiment.tuning import tune
from sb3_adc.experiment.tuning_storage import TUNING_ACTIVITY, study_lock

EXPERIMENT = """
description: probe
envs: [Pendulum-v1]
seeds: [0]
n_timesteps: 200
evaluation: {episodes: 1, final_episodes: 1}
configs:
  adc_small: {algo: adc, overrides: {learning_starts: 50, batch_size: 16, policy_kwargs: "dict(net_arch=[8])"}}
reference: adc_small
bootstrap_reps: 100
figures: ../figures
"""


def _experiment(folder: Path) -> tuple[Path, Path]:
    """An experiment file and its results folder (made, with no tables)."""
    path = folder / "experiments" / "probe.yml"
    path.parent.mkdir(parents=True)
    path.write_text(EXPERIMENT)
    results = folder / "results" / "probe"
    results.mkdir(parents=True)
    return path, results


def test_report_refuses_a_results_folder_in_use(tmp_path, monkeypatch, capsys):
    path, results = _experiment(tmp_path)
    written: list[str] = []
    monkeypatch.setattr(summary, "write_report", lambda *args, **kwargs: written.append("report"))
    with FolderLock(str(results), "running an experiment in it"):
        assert main(["experiment", str(path), "--report"]) == 2
    err = capsys.readouterr().err
    assert f"{results} is in use" in err
    assert "running the experiment or writing its report" in err
    assert written == []


def test_report_holds_the_results_folder_lock_while_it_writes(tmp_path, monkeypatch):
    path, results = _experiment(tmp_path)
    seen: list[str] = []

    def report(*args: Any, **kwargs: Any) -> None:
        # What an experiment started now would meet: the folder in use, by the report.
        with pytest.raises(RunLocked, match="is in use") as error:
            FolderLock(str(results), "running an experiment in it").acquire()
        seen.append(str(error.value))

    monkeypatch.setattr(summary, "write_report", report)
    assert main(["experiment", str(path), "--report"]) == 0
    assert len(seen) == 1
    with FolderLock(str(results)):  # released afterwards
        pass


#: A tiny study of one run (one seed, one evaluation): the quickest.
ONE_RUN: dict[str, Any] = {"seeds": (0,), "n_evaluations": 1}


def test_a_second_tuning_of_a_study_fails_at_once(tiny_study):
    settings = tiny_study(**ONE_RUN)
    with FolderLock(settings.study_dir, TUNING_ACTIVITY), pytest.raises(RunLocked, match="tuning its study"):
        tune(settings)
    assert not (Path(settings.study_dir) / "study.log").exists()  # nothing written by the second command


def test_the_cli_exits_2_for_a_study_in_use(tmp_path, capsys, tiny_study):
    settings = tiny_study(**ONE_RUN)
    args = ["train", "--algo", "ddpg", "--env", "Pendulum-v1", "-f", str(tmp_path), "-optimize", "--n-trials", "1"]
    with FolderLock(settings.study_dir, TUNING_ACTIVITY):
        assert main(args) == 2
    err = capsys.readouterr().err
    assert f"{settings.study_dir} is in use" in err
    assert "--n-jobs" in err
    assert not (Path(settings.study_dir) / "study.log").exists()


def test_tuning_holds_the_study_lock_while_its_trials_train(monkeypatch, tiny_study):
    settings = tiny_study(**ONE_RUN)
    real_train = tuning_trials.train
    seen: list[bool] = []

    def train(*args: Any, **kwargs: Any) -> Any:
        with pytest.raises(RunLocked):
            FolderLock(settings.study_dir).acquire()
        seen.append(True)
        return real_train(*args, **kwargs)

    monkeypatch.setattr(tuning_trials, "train", train)
    assert tune(settings).n_finished == 1
    assert seen == [True]
    with FolderLock(settings.study_dir):  # released when the study ends
        pass


def test_a_database_study_is_shared_without_a_lock(tmp_path, tiny_study):
    database = tiny_study(**ONE_RUN, storage=f"sqlite:///{tmp_path / 'study.db'}")
    journal = tiny_study(**ONE_RUN, storage=str(tmp_path / "shared.log"))
    assert not isinstance(study_lock(database), FolderLock)
    lock = study_lock(journal)
    assert isinstance(lock, FolderLock)
    assert lock.folder == journal.study_dir
