"""``sb3-adc train -optimize``: Optuna studies on the training engine, end to end through the command line."""

import csv

import optuna
import pytest
import yaml

from sb3_adc.config import load_hyperparams
from sb3_adc.experiment import FinalEvaluation, TrainSettings
from sb3_adc.experiment.tuning import TuneSettings
from sb3_adc.experiment.tuning_trials import TrialEvalCallback


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


def test_budget_is_written_into_the_trial_and_best_files(cli, train_args, tmp_path):
    """A study's ``-n`` (here 200, the entry says 300) is what its files train for with ``-conf``."""
    status, _, err = cli(*tune_args(train_args, "ddpg", tmp_path, "--n-trials", 2, "-n", 200))
    assert status == 0, err
    study_dir = tmp_path / "tuning" / "ddpg-Pendulum-v1"
    for path in (study_dir / "trial_0" / "hyperparams.yml", study_dir / "trial_1" / "hyperparams.yml"):
        assert yaml.safe_load(path.read_text())["Pendulum-v1"]["n_timesteps"] == 200
    assert load_hyperparams("ddpg", "Pendulum-v1", str(study_dir / "best_hyperparams.yml")).n_timesteps == 200


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


VALIDATION_LAYOUTS = "layout_seeds:[2000000,2000100]"
LIDAR = "sb3_adc/LidarObstacleCourse-v1"


def lidar_tune_args(train_args, log_folder, *extra):
    return [*train_args("adc", log_folder, env=LIDAR), "-optimize", "--n-evaluations", 2, "--n-startup-trials", 1, *extra]


def test_success_objective_tunes_on_the_validation_layouts(cli, train_args, tmp_path):
    """A trial's value is the final success rate, evaluated on the layouts of --eval-env-kwargs."""
    extra = ["--n-trials", 2, "--objective", "success", "--eval-env-kwargs", VALIDATION_LAYOUTS, "--final-eval-episodes", 4]
    status, out, err = cli(*lidar_tune_args(train_args, tmp_path, *extra))
    assert status == 0, err
    study_dir = tmp_path / "tuning" / "adc-sb3_adc-LidarObstacleCourse-v1"
    trials = read_trials(study_dir)
    assert len(trials) == 2
    for row in trials:
        run_dir = study_dir / f"trial_{row['number']}" / "seed_0"
        final = FinalEvaluation.load(run_dir / "sb3_adc-LidarObstacleCourse-v1" / "final_evaluation.json")
        assert len(final.successes) == 4
        # The value is the success rate, not the return.
        assert float(row["value"]) == pytest.approx(final.success_rate, abs=1e-3)
        assert float(row["success_seed_0"]) == pytest.approx(final.success_rate)
        assert float(row["return_seed_0"]) == pytest.approx(final.mean_return)
        assert TrainSettings.of_run(str(run_dir)).eval_env_kwargs == {"layout_seeds": [2_000_000, 2_000_100]}
    assert "mean final success rate" in out


def test_trial_evaluations_use_the_evaluation_keywords(tiny_conf):
    """The pruner's evaluations run on the layouts of ``eval_env_kwargs``, training on those of the entry."""
    settings = TuneSettings(
        algo="adc",
        env_id=LIDAR,
        conf_file=str(tiny_conf / "adc.yml"),
        objective="success",
        eval_env_kwargs={"layout_seeds": [2_000_000, 2_000_100]},
    )
    trial = optuna.create_study().ask()
    callback = TrialEvalCallback(trial, settings, str(tiny_conf / "adc.yml"), seed=0, step_offset=0)
    env = callback.eval_env.envs[0].unwrapped
    assert env.layout_seeds == (2_000_000, 2_000_100)
    callback.eval_env.close()


def test_success_objective_refused_where_episodes_report_no_success(cli, train_args, tmp_path):
    log_folder = tmp_path / "logs"
    status, _, err = cli(*tune_args(train_args, "adc", log_folder, "--objective", "success"))
    assert status == 2
    assert "--objective" in err
    assert "is_success" in err
    assert not log_folder.exists()


def test_search_space_file_adds_and_replaces_choices(cli, train_args, tmp_path):
    """Listed keys are drawn from their choices: new keys join the search, a searched key takes the listed range."""
    space = tmp_path / "space.yml"
    space.write_text("learning_rate: [0.002]\nbuffer_size: [500, 700]\ntrain_freq: [[1, step], [1, episode]]\n")
    status, _, err = cli(*tune_args(train_args, "adc", tmp_path / "logs", "--n-trials", 3, "--search-space", space))
    assert status == 0, err
    study_dir = tmp_path / "logs" / "tuning" / "adc-Pendulum-v1"
    trials = read_trials(study_dir)
    assert trials[0]["params"] == "{}"  # the shipped entry, as it is
    shipped = yaml.safe_load((study_dir / "trial_0" / "hyperparams.yml").read_text())["Pendulum-v1"]
    assert shipped["buffer_size"] == 1000
    for row in trials[1:]:
        sampled = yaml.safe_load(row["params"])
        entry = yaml.safe_load((study_dir / f"trial_{row['number']}" / "hyperparams.yml").read_text())["Pendulum-v1"]
        assert sampled["learning_rate"] == entry["learning_rate"] == 0.002
        assert entry["buffer_size"] == sampled["buffer_size"] in (500, 700)
        assert entry["train_freq"] == [[1, "step"], [1, "episode"]][sampled["train_freq_choice"]]
        # The algorithm's own space sees the listed learning rate: the critic's is a multiple of it.
        assert entry["critic_learning_rate"] == pytest.approx(0.002 * sampled["critic_rate_ratio"])
        assert "gamma" in sampled  # the rest of ADC's space is still searched


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("gamma: [0.9, 2]", "--search-space gamma"),
        ("gamma: 0.9", "--search-space gamma"),
        ("[gamma]", "--search-space"),
        ("n_timesteps: [100, 200]", "--search-space n_timesteps"),
        ("n_intervals: [4, 8]", "fixed by -params"),
    ],
)
def test_bad_search_space_exits_2_before_writing(cli, train_args, tmp_path, text, message):
    space = tmp_path / "space.yml"
    space.write_text(text + "\n")
    log_folder = tmp_path / "logs"
    status, _, err = cli(*tune_args(train_args, "adc", log_folder, "--search-space", space, "-params", "n_intervals:5"))
    assert status == 2
    assert message in err
    assert not log_folder.exists()


def test_missing_search_space_file_exits_2(cli, train_args, tmp_path):
    status, _, err = cli(*tune_args(train_args, "adc", tmp_path / "logs", "--search-space", tmp_path / "none.yml"))
    assert status == 2
    assert "--search-space" in err
