"""
The -v0 lidar course learned on its training course (``benchmarks/experiments/lidar_course_v0_plain.yml``, with the
Table 2 runs of ``paper_table2_lidar_course.yml``): the counts and numbers that ``docs/envs/lidar_course.rst``
(:ref:`lidar-transfer`) states come from the committed tables, and the file's transfer test sets (the training
course and the unseen course files) score a run.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
from test_prose_numbers import numbers, referenced_tables, rst_prose

from sb3_adc.experiment import test_sets as scoring
from sb3_adc.experiment.experiments import read_experiment, run_experiment
from sb3_adc_envs.lidar_course import shipped_courses

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENT = ROOT / "benchmarks" / "experiments" / "lidar_course_v0_plain.yml"
RESULTS = ROOT / "benchmarks" / "results"
PAGE = ROOT / "docs" / "envs" / "lidar_course.rst"
SUCCESS = 0.5  # 500 steps of +0.001 without a collision


def collision_free_runs(experiment: str) -> dict[str, int]:
    """Per configuration, the runs whose final evaluation drove every episode without a collision."""
    final = pd.read_csv(RESULTS / experiment / "final.csv")
    return {str(algo): int((group["mean_return"] >= SUCCESS).sum()) for algo, group in final.groupby("algo")}


def test_the_counts_the_page_states_are_the_committed_final_evaluations():
    assert collision_free_runs("lidar_course_v0_plain") == {"adc": 8, "adc_legendre": 8, "ddpg": 10, "td3_shipped": 8}
    assert collision_free_runs("paper_table2_lidar_course") == {"adc_table2": 0, "ddpg_table2": 8}


def test_training_is_not_monotonic_in_every_configuration():
    """In every configuration, runs that had reached 500 collision-free steps in every episode of an evaluation
    collide at a later one, and most of these are back at 500 steps by the end."""
    evaluations = pd.read_csv(RESULTS / "lidar_course_v0_plain" / "evaluations.csv")
    for algo, runs in evaluations.groupby("algo"):
        relapsed = recovered = 0
        for _, run in runs.groupby("seed"):
            returns = run.sort_values("timesteps")["mean_return"].to_numpy()
            reached = np.flatnonzero(returns >= SUCCESS)
            if reached.size and (returns[reached[0] :] < SUCCESS).any():
                relapsed += 1
                recovered += int(returns[-1] >= SUCCESS)
        assert relapsed > 0, algo
        assert recovered > relapsed / 2, algo


def test_the_section_numbers_are_in_the_tables_it_names():
    """As ``test_prose_numbers`` asks of the results pages, for the page's section on learning the course."""
    text = PAGE.read_text()
    section = text[text.index(".. _lidar-transfer:") :]
    following = re.search(r"^\.\. _", section[1:], re.M)
    section = section[: following.start() + 1] if following else section
    known = {number for table in referenced_tables(PAGE, section) for number in numbers(table.read_text())}
    typed = sorted(set(numbers(rst_prose(section))) - known)
    assert not typed, f"numbers of the section that no table it names holds: {typed}"


def test_the_transfer_test_sets_cover_every_shipped_course():
    experiment = read_experiment(str(EXPERIMENT))
    sets = experiment.test_sets
    assert list(sets) == ["exact start", "training course", "unseen paths and widths", "unseen obstacle courses"]
    courses = [course for test in sets.values() for course in test.courses or []]
    assert sorted(set(courses)) == sorted(shipped_courses())
    assert sets["exact start"].env_kwargs == {"start_position_jitter": 0.0, "start_heading_jitter_deg": 0.0}
    assert sets["exact start"].episodes == 1
    for name in ("training course", "unseen paths and widths", "unseen obstacle courses"):
        assert sets[name].env_kwargs == {"start_position_jitter": 0.1, "start_heading_jitter_deg": 10.0}
        assert (sets[name].episodes, sets[name].model) == (20, "final")


def test_the_test_sets_score_a_tiny_run(monkeypatch, tmp_path):
    """The file's pipeline on a tiny budget, one configuration: each test set plays its first course."""
    experiment = read_experiment(str(EXPERIMENT))
    experiment = dataclasses.replace(experiment, configs={"adc_legendre": experiment.configs["adc_legendre"]})
    real_score = scoring.score

    def score_and_keep(runs, test_sets, output, workers=1):
        real_score(runs, test_sets, output, workers)
        shutil.copy(Path(output) / scoring.EPISODES_CSV, tmp_path)

    monkeypatch.setattr(scoring, "score", score_and_keep)
    outcomes = run_experiment(experiment, workers=1, tiny=True)
    assert [outcome.status for outcome in outcomes] == ["trained"]
    episodes = pd.read_csv(tmp_path / scoring.EPISODES_CSV)
    first = {name: test.courses[0] for name, test in experiment.test_sets.items() if test.courses}
    assert dict(zip(episodes["test_set"], episodes["course"], strict=True)) == first
    assert episodes["length"].between(1, 500).all()
    assert (episodes["success"] == (episodes["length"] == 500)).all()
