"""
Experiments as data: every file of ``benchmarks/experiments/`` reads, resolves to the settings recorded with its
committed results, regenerates its committed summary from its committed tables, and runs end to end on a tiny
budget; bad files are refused with the key named (exit status 2 at the CLI) before anything is written.
"""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sb3_adc.cli import main
from sb3_adc.experiment import test_sets as scoring
from sb3_adc.experiment.experiments import ExperimentError, read_experiment, repository_root, run_experiment
from sb3_adc.experiment.summary import diagnostics_summary, display_table, summary
from sb3_adc.experiment.tuning_grid import record as tuning_record

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted((ROOT / "benchmarks" / "experiments").glob("*.yml"))
IDS = [path.stem for path in FILES]
RECORDED = ("configs", "reference", "envs", "seeds", "n_timesteps", "resolved")
#: What the metadata of a tuning file's results records of its studies (an older one lacks the last four).
TUNING_RECORDED = ("env", "seeds", "n_trials", "n_timesteps", "sampler", "pruner")
TUNING_RECORDED += ("fixed", "starting_points", "search_space", "eval_env_kwargs")


def test_there_are_experiment_files():
    assert len(FILES) >= 10


@pytest.mark.parametrize("path", FILES, ids=IDS)
def test_file_resolves_to_the_settings_recorded_with_its_results(path):
    """Re-running the file trains what its committed results were trained with (entries, overrides, grid)."""
    experiment = read_experiment(str(path))
    if not Path(experiment.results).is_dir():
        pytest.skip(f"not run yet: no results committed in {Path(experiment.results).relative_to(ROOT)}")
    metadata = json.loads((Path(experiment.results) / "metadata.json").read_text())
    if experiment.tuning is not None:  # the studies' settings: budget, seeds, sampler, starting points, spaces
        record = json.loads(json.dumps(tuning_record(experiment)))
        recorded = [key for key in TUNING_RECORDED if key in metadata]
        assert set(TUNING_RECORDED[:6]) <= set(recorded)
        assert {key: record[key] for key in recorded} == {key: metadata[key] for key in recorded}

        def objective(text):  # an older metadata does not name the quantity when it is the return
            return re.sub(r"'s return", "", text)

        assert objective(record["objective"]) == objective(metadata["objective"])
        return
    record = json.loads(json.dumps(experiment.record(repository_root(experiment))))
    assert {key: record[key] for key in RECORDED} == {key: metadata[key] for key in RECORDED}
    assert metadata["experiment"] == f"benchmarks/experiments/{path.name}"


#: Columns of the summary that do not depend on the bootstrap replications (point estimates and counts).
POINT_COLUMNS = ("env", "config", "n_runs", "final_iqm", "final_mean", "final_std", "auc_iqm", "auc_mean")


def regenerated_summary(experiment, reps):
    results = Path(experiment.results)
    tables = {name: pd.read_csv(results / f"{name}.csv") for name in ("final", "evaluations", "episodes")}
    return summary(tables["final"], tables["evaluations"], reps, experiment.reference, tables["episodes"])


def assert_same_columns(regenerated, expected, columns):
    for column in columns:
        if expected[column].dtype == object:
            assert regenerated[column].tolist() == expected[column].tolist(), column
        else:
            np.testing.assert_allclose(regenerated[column].to_numpy(float), expected[column].to_numpy(float), rtol=1e-9)


@pytest.mark.parametrize("path", FILES, ids=IDS)
def test_summary_point_estimates_regenerate_from_the_committed_tables(path):
    """The committed ``summary.csv`` is what the engine computes from the committed run tables (its point
    estimates here, with few bootstrap replications; every column for one experiment below)."""
    experiment = read_experiment(str(path))
    committed = Path(experiment.results) / "summary.csv"
    if not committed.is_file():
        pytest.skip("no summary committed with these results")
    expected = pd.read_csv(committed)
    regenerated = regenerated_summary(experiment, reps=100)
    assert list(regenerated.columns) == list(expected.columns)
    points = [*POINT_COLUMNS, *[column for column in ("run_time_s_median", "p_improvement_of_adc") if column in expected]]
    assert_same_columns(regenerated, expected, points)


def test_summary_regenerates_with_its_confidence_intervals():
    """Every column of the summary the README's Pendulum row is built from, intervals included."""
    experiment = read_experiment(str(ROOT / "benchmarks" / "experiments" / "noisy_pendulum_shipped.yml"))
    expected = pd.read_csv(Path(experiment.results) / "summary.csv")
    assert_same_columns(regenerated_summary(experiment, experiment.bootstrap_reps), expected, expected.columns)


def test_summary_table_rounds_to_the_scale_of_each_environments_returns():
    """Returns of order one keep three decimals (one would read 0.026 and -0.165 as 0.0 and -0.2); the Pendulum's one."""
    results = ROOT / "benchmarks" / "results"
    names = ("noisy_pendulum_shipped", "speed_mechanisms_screen")
    pendulum, lidar = (pd.read_csv(results / name / "summary.csv") for name in names)
    table = display_table(pd.concat([pendulum, lidar], ignore_index=True), "adc")
    first = pendulum.iloc[0]
    assert table.iloc[0]["final IQM [95% CI]"].startswith(f"{first.final_iqm:.1f} [{first.final_iqm_ci_low:.1f}, ")
    row = lidar.iloc[2]
    cell = table.iloc[len(pendulum) + 2]["final IQM [95% CI]"]
    assert cell == f"{row.final_iqm:.3f} [{row.final_iqm_ci_low:.3f}, {row.final_iqm_ci_high:.3f}]"
    assert abs(float(cell.split()[0]) - row.final_iqm) < 5e-4


@pytest.mark.parametrize("path", FILES, ids=IDS)
def test_test_set_summary_regenerates_from_the_committed_run_rates(path):
    """The committed ``test_summary.csv`` (the lidar rows of the README) is what the engine computes from the
    committed per-run success rates, intervals and P(reference > configuration) included."""
    experiment = read_experiment(str(path))
    results = Path(experiment.results)
    if not (results / "test_summary.csv").is_file():
        pytest.skip("no test sets scored with these results")
    expected = pd.read_csv(results / "test_summary.csv")
    regenerated = scoring.summary(pd.read_csv(results / "test_runs.csv"), experiment.references(), experiment.bootstrap_reps)
    assert list(regenerated.columns) == list(expected.columns)
    numbers = [column for column in expected.columns if expected[column].dtype != object]
    assert_same_columns(regenerated, expected, ["env", "test_set", "config", *numbers])
    assert regenerated["reference"].fillna("").tolist() == expected["reference"].fillna("").tolist()


@pytest.mark.parametrize("path", FILES, ids=IDS)
def test_file_runs_end_to_end_on_a_tiny_budget(path, capsys):
    experiment = read_experiment(str(path))
    if experiment.tuning is not None:  # every study, two trials of a few hundred steps, and the summary
        assert main(["experiment", str(path), "--tiny", "--workers", "1"]) == 0
        assert f"{path.stem} runs: {len(experiment.configs)} tiny studies" in capsys.readouterr().out
        return
    outcomes = run_experiment(experiment, workers=1, tiny=True)
    errors = [outcome.error for outcome in outcomes if outcome.error]  # a failed run's traceback, in the report
    assert [outcome.status for outcome in outcomes] == ["trained"] * len(experiment.configs), errors
    assert {outcome.spec.algo for outcome in outcomes} == {config.algo for config in experiment.configs.values()}


def write(folder: Path, text: str) -> Path:
    path = folder / "experiments" / "probe.yml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


GOOD = """
description: probe
envs: [Pendulum-v1]
seeds: [0, 1]
n_timesteps: 200
evaluation: {episodes: 1, final_episodes: 2, every: 100}
configs:
  adc_small: {algo: adc, overrides: {learning_starts: 50, batch_size: 16, policy_kwargs: "dict(net_arch=[8])"}}
  ddpg_small: {algo: ddpg, overrides: {learning_starts: 50, batch_size: 16, policy_kwargs: "dict(net_arch=[8])"}, label: DDPG}
reference: adc_small
bootstrap_reps: 100
figures: ../figures
"""


@pytest.mark.parametrize(
    ("replace", "key"),
    [
        (("seeds: [0, 1]", "seeds: [0, 0]"), "seeds"),
        (("algo: adc,", "algo: a2c,"), "configs.adc_small.algo"),
        (("reference: adc_small", "reference: td3"), "reference"),
        (("n_timesteps: 200", "n_timesteps: -5"), "n_timesteps"),
        (("bootstrap_reps: 100", "bootstrap_reps: 100\nbudget: 3"), "the file"),
        (("{episodes: 1, final_episodes: 2, every: 100}", "{episodes: 0}"), "evaluation.episodes"),
        (("final_episodes: 2, every: 100}", "final_episodes: 2, every: 0}"), "evaluation.every"),
        (("figures: ../figures", "tuning: {trials: 2}"), "evaluation.every"),
        (("figures: ../figures", "test_sets: [a, b]"), "test_sets"),
        (("figures: ../figures", "test_sets: {plain: {episodes: 0}}"), "test_sets.plain.episodes"),
        (("figures: ../figures", "test_sets: {plain: {model: last}}"), "test_sets.plain.model"),
        (("figures: ../figures", "test_sets: {plain: {seeds: 3}}"), "test_sets.plain"),
        (("figures: ../figures", "test_sets: {new: {layout_seeds: {start: 5, stop: 5}}}"), "test_sets.new.layout_seeds"),
        (
            ("figures: ../figures", "test_sets: {new: {layout_seeds: {start: 0, stop: 2}, courses: [a]}}"),
            "test_sets.new.courses",
        ),
        (("figures: ../figures", "test_sets: {new: {env_kwargs: [1]}}"), "test_sets.new.env_kwargs"),
        (("label: DDPG}", "label: DDPG, reference: td3}"), "configs.ddpg_small.reference"),
        (("figures: ../figures", "diagnostics: {every: 0}"), "diagnostics.every"),
        (("figures: ../figures", "diagnostics: {every: 10, eval_env: x}"), "diagnostics"),
        (("envs: [Pendulum-v1]", "envs: [Pendulum-v1, MountainCarContinuous-v0]\ndiagnostics: {}"), "diagnostics"),
        # A tuning file: each key refused where it is defined.
        (("figures: ../figures", "tuning: {trials: 0}"), "tuning.trials"),
        (("figures: ../figures", "tuning: {objective: return}"), "tuning.trials"),
        (("figures: ../figures", "tuning: {trials: 2, sampler: grid}"), "tuning.sampler"),
        (("figures: ../figures", "tuning: {trials: 2, objective: cost}"), "tuning.objective"),
        (("figures: ../figures", "tuning: {trials: 2, n_evaluations: 0}"), "tuning.n_evaluations"),
        (("figures: ../figures", "tuning: {trials: 2, budget: 3}"), "tuning"),
        (("figures: ../figures", "tuning: {trials: 2, fixed: [1]}"), "tuning.fixed"),
        (("envs: [Pendulum-v1]", "envs: [Pendulum-v1, MountainCarContinuous-v0]\ntuning: {trials: 2}"), "envs"),
        (("label: DDPG}", "label: DDPG, search_space: {tau: [0.01]}}"), "configs.ddpg_small.search_space"),
        (("label: DDPG}", "search_space: {tau: 0.01}}\ntuning: {trials: 2}"), "configs.ddpg_small.search_space"),
        (("label: DDPG}", "search_space: {batch_size: [8]}}\ntuning: {trials: 2}"), "configs.ddpg_small.search_space"),
        (
            ("{episodes: 1, final_episodes: 2, every: 100}", "{episodes: 1}\ntuning: {trials: 2, n_startup_trials: -1}"),
            "tuning.n_startup_trials",
        ),
    ],
)
def test_bad_files_are_refused_naming_the_key(tmp_path, replace, key, capsys):
    path = write(tmp_path, GOOD.replace(*replace))
    with pytest.raises(ExperimentError, match=f"`{key}`"):
        read_experiment(str(path))
    assert main(["experiment", str(path)]) == 2
    assert f"`{key}`" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()
    assert not (tmp_path / "results").exists()


def test_invalid_override_is_refused_before_anything_runs(tmp_path, capsys):
    path = write(tmp_path, GOOD.replace("learning_starts: 50, batch_size", "learning_starts: 50, batch_sise"))
    assert main(["experiment", str(path)]) == 2
    assert "batch_sise" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


def test_cli_trains_resumes_and_reports(tmp_path, capsys):
    path = write(tmp_path, GOOD)
    assert main(["experiment", str(path), "--workers", "2"]) == 0
    results = tmp_path / "results" / "probe"
    final = pd.read_csv(results / "final.csv")
    assert sorted(final["algo"].unique()) == ["adc_small", "ddpg_small"]
    assert len(final) == 4
    table = pd.read_csv(results / "summary.csv").set_index("config")
    assert table.loc["adc_small", "n_runs"] == 2
    assert np.isnan(table.loc["adc_small", "p_improvement_of_adc"])
    assert 0.0 <= table.loc["ddpg_small", "p_improvement_of_adc"] <= 1.0
    metadata = json.loads((results / "metadata.json").read_text())
    assert metadata["configs"]["ddpg_small"]["hyperparams"] == "shipped"
    assert metadata["configs"]["ddpg_small"]["overrides"]["batch_size"] == 16
    assert metadata["resolved"]["adc_small"]["Pendulum-v1"]["n_timesteps"] == 200
    # The curves keep the configurations' names; the figures are drawn with the labels.
    assert set(pd.read_csv(results / "curves.csv")["algo"]) == {"adc_small", "ddpg_small"}
    assert (tmp_path / "figures" / "probe_learning_curves.png").is_file()
    assert not list(results.glob("*.png"))
    # `evaluation.every`: each run evaluated at 100 and 200 steps, and the metadata says so.
    evaluations = pd.read_csv(results / "evaluations.csv")
    assert evaluations.groupby(["algo", "seed"])["timesteps"].apply(list).tolist() == [[100, 200]] * 4
    assert "every 100 steps" in metadata["eval"]
    # An invocation killed before its report (its journal entry unfinished) keeps its wall time in the metadata.
    journal = tmp_path / "runs" / "probe" / "adc_small" / "invocations.json"
    entries = json.loads(journal.read_text())
    killed = {**entries[0], "id": "killed", "wall_time_s": 1234.5, "finished": False}
    journal.write_text(json.dumps([*entries, killed]))
    # A second invocation finds every run finished and trains nothing.
    capsys.readouterr()
    assert main(["experiment", str(path), "--workers", "2"]) == 0
    assert capsys.readouterr().out.count("skipped") == 4
    metadata = json.loads((results / "metadata.json").read_text())
    wall_times = list(metadata["wall_time_s_per_invocation"].values())
    assert len(wall_times) == 3
    assert 1234.5 in wall_times
    # --report rewrites the summary from the tables alone, and leaves the training's metadata as it is.
    (results / "summary.csv").unlink()
    assert main(["experiment", str(path), "--report"]) == 0
    assert (results / "summary.csv").is_file()
    assert json.loads((results / "metadata.json").read_text()) == metadata


def test_test_sets_score_each_finished_run_once(tmp_path, monkeypatch):
    """Each finished run's final model plays the test set's episodes; a second invocation rescores nothing, and a
    changed test set is scored again."""
    import sb3_adc.experiment.test_sets as test_sets

    text = GOOD.replace("figures: ../figures", "test_sets:\n  slow: {env_kwargs: {g: 5.0}, episodes: 2}")
    path = write(tmp_path, text)
    assert main(["experiment", str(path), "--workers", "1"]) == 0
    results = tmp_path / "results" / "probe"
    episodes = pd.read_csv(results / "test_episodes.csv")
    assert len(episodes) == 2 * 2 * 2  # configurations x seeds x episodes
    assert set(episodes.columns) >= {"config", "env", "seed", "test_set", "episode", "success", "return", "length", "hit"}
    assert (episodes["length"] == 200).all()
    assert not episodes["success"].any()
    rates = pd.read_csv(results / "test_runs.csv")
    assert len(rates) == 4
    assert (rates["episodes"] == 2).all()
    table = pd.read_csv(results / "test_summary.csv").set_index("config")
    assert table.loc["ddpg_small", "reference"] == "adc_small"
    assert table.loc["ddpg_small", "p_reference"] == 0.5
    metadata = json.loads((results / "metadata.json").read_text())
    assert metadata["test_sets"]["slow"] == {
        "env_kwargs": {"g": 5.0},
        "layout_seeds": None,
        "courses": None,
        "episodes": 2,
        "model": "final",
    }
    calls = []
    monkeypatch.setattr(test_sets, "score_run", lambda *args: calls.append(args) or [])
    assert main(["experiment", str(path), "--workers", "1"]) == 0
    assert calls == []
    path.write_text(text.replace("5.0}, episodes: 2}", "5.0}, episodes: 3}"))
    assert main(["experiment", str(path), "--workers", "1"]) == 0
    assert len(calls) == 4


def test_paths_are_relative_to_the_file(tmp_path):
    path = write(tmp_path, GOOD + "runs: ../elsewhere/runs\nresults: ../elsewhere/results\n")
    experiment = read_experiment(str(path))
    assert experiment.runs == str(tmp_path / "elsewhere" / "runs")
    assert experiment.results == str(tmp_path / "elsewhere" / "results")
    shutil.rmtree(tmp_path / "experiments")


def test_ctrl_c_exits_130_with_the_resume_message(tmp_path, monkeypatch, capsys):
    import sb3_adc.experiment.experiments as experiments

    def ctrl_c(*_, **__):
        # What the engine raises when Ctrl-C reaches a grid (each run in progress saved its checkpoint first).
        raise KeyboardInterrupt

    monkeypatch.setattr(experiments, "run_benchmarks", ctrl_c)
    assert main(["experiment", str(write(tmp_path, GOOD))]) == 130
    assert "Re-run the same command to continue" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["experiment", "benchmark"])
def test_workers_out_of_range_are_refused_by_both_grid_commands(tmp_path, capsys, command):
    grid = [str(write(tmp_path, GOOD))] if command == "experiment" else ["--algos", "adc", "--envs", "Pendulum-v1"]
    assert main([command, *grid, "--workers", "0", *([] if command == "experiment" else ["-f", str(tmp_path / "b")])]) == 2
    assert "--workers must be between 1 and" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()
    assert not (tmp_path / "runs").exists()


def test_diagnostics_are_logged_per_run_and_summarised(tmp_path):
    """With ``diagnostics``, every run logs its critic diagnostics to its own folder (one setting serves the grid's
    seeds), and the experiment collects them: each run's history, the last records, the IQM with CIs, the figure."""
    path = write(tmp_path, GOOD + "diagnostics: {every: 100, episodes: 1}\n")
    experiment = read_experiment(str(path))
    assert experiment.record(str(tmp_path))["diagnostics"] == {"every": 100, "episodes": 1}
    outcomes = run_experiment(experiment, workers=1)
    assert [outcome.status for outcome in outcomes] == ["trained"] * 4
    results = tmp_path / "results" / "probe"
    assert sorted(path.name for path in (results / "diagnostics").iterdir()) == [
        f"{name}_seed{seed}.csv" for name in ("adc_small", "ddpg_small") for seed in (0, 1)
    ]
    history = pd.read_csv(results / "diagnostics" / "adc_small_seed1.csv")
    assert history["timesteps"].tolist() == [100, 200]
    last = pd.read_csv(results / "diagnostics_last_records.csv")
    assert sorted(zip(last["config"], last["seed"], strict=True)) == [
        ("adc_small", 0),
        ("adc_small", 1),
        ("ddpg_small", 0),
        ("ddpg_small", 1),
    ]
    assert last["eval/critic_bias"].notna().all()
    assert last.set_index("config")["train/advantage_roughness"].loc["ddpg_small"].isna().all()  # ADC only
    summary = pd.read_csv(results / "diagnostics_summary.csv")
    assert set(summary["metric"]) == {"eval/critic_bias", "eval/critic_bias_abs", "train/advantage_roughness"}
    roughness = summary[summary["metric"] == "train/advantage_roughness"]
    assert roughness["config"].tolist() == ["adc_small"]
    assert roughness["n_runs"].tolist() == [2]
    assert (tmp_path / "figures" / "probe_diagnostics.png").is_file()


def test_diagnostics_summary_regenerates_from_the_committed_last_records():
    """The committed ``diagnostics_summary.csv`` (the critic-designs page's diagnostics) is what the engine computes
    from the committed last record of each run."""
    experiment = read_experiment(str(ROOT / "benchmarks" / "experiments" / "noisy_pendulum_critics.yml"))
    results = Path(experiment.results)
    expected = pd.read_csv(results / "diagnostics_summary.csv")
    regenerated = diagnostics_summary(pd.read_csv(results / "diagnostics_last_records.csv"), experiment.bootstrap_reps)
    assert_same_columns(regenerated, expected, expected.columns)
