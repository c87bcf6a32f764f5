"""The committed equal-budget studies of the tuning files (``fair_tuning*.yml``,
``highway_obstacle_v1_tuning.yml``) agree with themselves: every algorithm had the same number of finished trials, a
trial's value is the mean of its seeds, the winner files hold the best trial, and each summary and its trial times
(where recorded) rebuild from the trials."""

from __future__ import annotations

import csv
import json
import re
import shutil
from pathlib import Path

import pytest

from sb3_adc.experiment.experiments import read_experiment
from sb3_adc.experiment.tuning_grid import summarise

ROOT = Path(__file__).resolve().parents[2]
#: The results of every tuning file (``tuning:``): the folders with a study's trials (a folder of hyperparameter files
#: alone can be the entries an experiment read, e.g. highway_obstacle_v1's from before its tuning).
FOLDERS = sorted({path.parents[1] for path in (ROOT / "benchmarks" / "results").glob("*/*/trials.csv")})


def trials_of(folder: Path) -> dict[str, list[dict[str, str]]]:
    studies = {}
    for trials_csv in sorted(folder.glob("*/trials.csv")):
        with open(trials_csv, encoding="utf-8") as stream:
            studies[trials_csv.parent.name] = list(csv.DictReader(stream))
    return studies


@pytest.mark.parametrize("folder", FOLDERS, ids=[folder.name for folder in FOLDERS])
def test_equal_budgets_values_and_winners(folder):
    metadata = json.loads((folder / "metadata.json").read_text())
    studies = trials_of(folder)
    assert studies
    measure = "success" if "success" in metadata["objective"] else "return"
    for algo, trials in studies.items():
        finished = [row for row in trials if row["state"] in ("COMPLETE", "PRUNED")]
        assert len(finished) == metadata["n_trials"], algo
        complete = [row for row in trials if row["state"] == "COMPLETE"]
        for row in complete:
            seeds = [float(row[f"{measure}_seed_{seed}"]) for seed in metadata["seeds"]]
            assert float(row["value"]) == pytest.approx(sum(seeds) / len(seeds), abs=1e-3), (algo, row["number"])
        best = max(complete, key=lambda row: float(row["value"]))
        header = (folder / "hyperparams" / f"{algo}.yml").read_text().splitlines()[0]
        named = re.search(r"\((?:trial (\d+)|the shipped entry)\)", header)
        assert named is not None, header
        assert (named.group(1) or "0") == best["number"], (algo, header)
        assert f"of {metadata['n_trials']} trials" in header


#: The studies whose metadata records the trials' time (those run since it does): their summaries must rebuild.
REBUILT = [folder for folder in FOLDERS if "trial_time_s" in json.loads((folder / "metadata.json").read_text())]


@pytest.mark.parametrize("folder", REBUILT, ids=[folder.name for folder in REBUILT])
def test_summary_and_trial_times_rebuild_from_the_trials(tmp_path, folder):
    metadata = json.loads((folder / "metadata.json").read_text())
    for algo in trials_of(folder):
        (tmp_path / algo).mkdir()
        shutil.copy(folder / algo / "trials.csv", tmp_path / algo / "trials.csv")
    experiment = read_experiment(str(ROOT / "benchmarks" / "experiments" / f"{folder.name}.yml"))
    _, trial_time = summarise(experiment, str(tmp_path), experiment.seeds)
    assert (tmp_path / "summary.md").read_text() == (folder / "summary.md").read_text()
    assert trial_time == metadata["trial_time_s"]
    if "starting_points" in metadata:
        assert set(metadata["starting_points"]) == set(trials_of(folder))


def test_fresh_seed_configs_are_the_winners():
    """Each algorithm of ``configs/procedural_generalisation/fair_tuning_lidar.yml``, applied to its starting entry
    (``configs/starting_entries/``, what ``procedural_generalisation.py --configs`` overrides) as ``-params`` are,
    is the winner file of its lidar study."""
    from sb3_adc.config.loader import apply_overrides, read_hyperparams_file, select_entry

    env_id = "sb3_adc/LidarObstacleCourse-v1"
    path = ROOT / "benchmarks" / "configs" / "procedural_generalisation" / "fair_tuning_lidar.yml"
    configs = read_hyperparams_file(str(path))
    assert configs
    for algo, overrides in configs.items():
        start_path = ROOT / "benchmarks" / "configs" / "starting_entries" / f"{algo}.yml"
        start, _ = select_entry(read_hyperparams_file(str(start_path)), env_id, str(start_path))
        winner_path = ROOT / "benchmarks" / "results" / "fair_tuning_lidar" / "hyperparams" / f"{algo}.yml"
        winner, _ = select_entry(read_hyperparams_file(str(winner_path)), env_id, str(winner_path))
        assert apply_overrides(start, overrides) == dict(winner), algo
