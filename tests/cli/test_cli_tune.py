"""``sb3-adc train -optimize``: Optuna studies on the training engine, end to end through the command line."""

import csv

import optuna
import pytest
import yaml

from sb3_adc.config import load_hyperparams


def tune_args(train_args, algo, log_folder, *extra):
    return [*train_args(algo, log_folder), "-optimize", "--n-evaluations", 2, "--n-startup-trials", 1, *extra]


def read_trials(study_dir):
    with open(study_dir / "trials.csv", encoding="utf-8") as stream:
        return list(csv.DictReader(stream))


def test_two_trials_shipped_first_best_file_loads(cli, train_args, tmp_path):
    status, out, err = cli(*tune_args(train_args, "adc", tmp_path, "--n-trials", 2))
    assert status == 0, err
    study_dir = tmp_path / "tuning" / "adc-Pendulum-v1"
    trials = read_trials(study_dir)
    assert [row["state"] for row in trials if row["state"] in ("COMPLETE", "PRUNED")]
    assert len(trials) == 2
    assert trials[0]["shipped"] == "True"
    assert trials[0]["params"] == "{}"
    assert trials[1]["shipped"] == "False"
    assert "critic_design" in trials[1]["params"]
    # Each trial's runs are ordinary run folders with a final evaluation.
    assert (study_dir / "trial_0" / "seed_0" / "Pendulum-v1" / "config.yml").is_file()
    # The sampled values are what the trial trained with.
    sampled = yaml.safe_load(trials[1]["params"])
    entry = yaml.safe_load((study_dir / "trial_1" / "hyperparams.yml").read_text())["Pendulum-v1"]
    for key in ("gamma", "batch_size", "critic_design", "n_intervals", "noise_type"):
        assert entry[key] == sampled[key]
    assert entry["critic_learning_rate"] == pytest.approx(entry["learning_rate"] * sampled["critic_rate_ratio"])
    best = study_dir / "best_hyperparams.yml"
    config = load_hyperparams("adc", "Pendulum-v1", str(best))
    assert config.n_timesteps == 300
    assert "Best:" in out


def test_rerun_continues_the_study_to_the_new_budget(cli, train_args, tmp_path):
    assert cli(*tune_args(train_args, "ddpg", tmp_path, "--n-trials", 2))[0] == 0
    status, out, _ = cli(*tune_args(train_args, "ddpg", tmp_path, "--n-trials", 3))
    assert status == 0
    assert "2 of 3 trials finished" in out
    trials = read_trials(tmp_path / "tuning" / "ddpg-Pendulum-v1")
    assert len(trials) == 3
    assert sum(row["shipped"] == "True" for row in trials) == 1


def test_shared_storage_and_study_name(cli, train_args, tmp_path):
    """Two log folders (two machines) on one journal file share one study and its trial budget."""
    storage = tmp_path / "shared.log"
    common = ["--storage", storage, "--study-name", "shared"]
    assert cli(*tune_args(train_args, "adc", tmp_path / "a", "--n-trials", 2, *common))[0] == 0
    status, out, _ = cli(*tune_args(train_args, "adc", tmp_path / "b", "--n-trials", 3, *common))
    assert status == 0
    assert "2 of 3 trials finished" in out
    study = optuna.load_study(
        study_name="shared",
        storage=optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(str(storage))),
    )
    assert len(study.trials) == 3
    assert not (tmp_path / "b" / "tuning" / "shared" / "trial_0").exists()  # ran in the first folder


def test_fixed_params_are_not_searched(cli, train_args, tmp_path):
    status, _, err = cli(*tune_args(train_args, "adc", tmp_path, "--n-trials", 2, "-params", "gamma:0.5", "n_intervals:7"))
    assert status == 0, err
    study_dir = tmp_path / "tuning" / "adc-Pendulum-v1"
    sampled = yaml.safe_load(read_trials(study_dir)[1]["params"])
    assert "gamma" not in sampled
    assert "n_intervals" not in sampled
    for trial in ("trial_0", "trial_1"):
        entry = yaml.safe_load((study_dir / trial / "hyperparams.yml").read_text())["Pendulum-v1"]
        assert entry["gamma"] == 0.5
        assert entry["n_intervals"] == 7


def test_two_workers_run_exactly_the_budget(cli, train_args, tmp_path):
    status, _, err = cli(*tune_args(train_args, "ddpg", tmp_path, "--n-trials", 3, "--n-jobs", 2))
    assert status == 0, err
    trials = read_trials(tmp_path / "tuning" / "ddpg-Pendulum-v1")
    assert len(trials) == 3
    assert all(row["state"] in ("COMPLETE", "PRUNED") for row in trials)


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--sampler", "grid", "--sampler"),
        ("--pruner", "hyperband", "--pruner"),
        ("--n-trials", "0", "--n-trials"),
        ("--n-jobs", "0", "--n-jobs"),
        ("--tuning-seeds", "-1", "--tuning-seeds"),
    ],
)
def test_bad_tuning_options_exit_2_before_writing(cli, train_args, tmp_path, option, value, message):
    log_folder = tmp_path / "logs"
    status, _, err = cli(*tune_args(train_args, "adc", log_folder, option, value))
    assert status == 2
    assert message in err
    assert not log_folder.exists()


def test_bad_hyperparameters_exit_2_before_writing(cli, train_args, tmp_path):
    log_folder = tmp_path / "logs"
    status, _, err = cli(*tune_args(train_args, "adc", log_folder, "-params", "gamma:2"))
    assert status == 2
    assert "gamma" in err
    assert not log_folder.exists()


def test_optimize_refuses_resume(cli, train_args, tmp_path):
    status, _, err = cli(*tune_args(train_args, "adc", tmp_path, "--resume"))
    assert status == 2
    assert "--resume" in err
