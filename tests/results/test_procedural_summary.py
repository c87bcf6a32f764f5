"""``benchmarks/procedural_summary.py``: the pooling of the course files, and the committed summary is that of every
committed grid (a grid committed without re-running the summary fails here)."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def summary_module():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    yield importlib.import_module("procedural_summary")
    sys.path.remove(str(ROOT / "benchmarks"))


def test_course_files_pool_episodes_per_run_without_training_or_held_out(summary_module):
    success = pd.DataFrame(
        [
            # test_set, algo, seed, episodes, successes
            ("held-out layouts", "td3", 1, 100, 0),
            ("training", "td3", 1, 10, 0),
            ("unseen_a", "td3", 1, 10, 7),
            ("unseen_b", "td3", 1, 30, 30),
            ("unseen_a", "td3", 2, 10, 1),
            ("unseen_b", "td3", 2, 30, 0),
            ("unseen_a", "adc", 1, 10, 10),
        ],
        columns=["test_set", "algo", "seed", "episodes", "successes"],
    )
    rates = summary_module.course_file_rates(success).set_index(["algo", "seed"])["success_rate"]
    # Pooled by episodes (37 of 40), not the mean of the files' rates (0.85).
    assert rates.loc[("td3", 1)] == pytest.approx(37 / 40)
    assert rates.loc[("td3", 2)] == pytest.approx(1 / 40)
    assert rates.loc[("adc", 1)] == 1.0
    assert len(rates) == 3


@pytest.fixture(scope="module")
def rebuilt(summary_module):
    return summary_module.summarise(summary_module.RESULTS_DIR)


def test_committed_summary_is_that_of_every_committed_grid(summary_module, rebuilt):
    results = summary_module.RESULTS_DIR
    committed = pd.read_csv(results / "summary.csv")
    pd.testing.assert_frame_equal(committed, rebuilt, check_dtype=False, atol=1e-9)
    assert set(committed["grid"]) >= {folder.name for folder in summary_module.grids(results)}
    comparisons = summary_module.compare(results, summary_module.COMPARISONS, reps=summary_module.COMPARISON_REPS)
    # Every pair of grids it names is committed and compared.
    assert len(comparisons) == 3 * len(summary_module.COMPARISONS)
    pd.testing.assert_frame_equal(pd.read_csv(results / "comparisons.csv"), comparisons, check_dtype=False, atol=1e-9)
    expected = summary_module.markdown(rebuilt, summary_module.held_out_obstacles())
    assert (results / "summary.md").read_text() == expected + summary_module.comparisons_markdown(comparisons)


def test_held_out_rows_are_the_grids_own_statistics_and_counts(summary_module, rebuilt):
    """The held-out IQM is the grid's (not a second bootstrap) and the count of runs at the target is the runs'."""
    for folder in summary_module.grids(summary_module.RESULTS_DIR):
        rows = rebuilt[rebuilt["grid"] == folder.name]
        held_out = rows[rows["test_set"] == "held-out layouts"].set_index("algo")
        grid = pd.read_csv(folder / "success_rates.csv")
        grid = grid[grid["test_set"] == "held-out layouts"].set_index("algo")
        pd.testing.assert_series_equal(held_out["iqm"], grid["iqm"], check_names=False)
        # Printed alike in both files: the summary reads the grid's floats back exactly (one unit in the last place
        # flips a rate such as 0.925 between 0.92 and 0.93).
        lines = (folder / "success_rates.md").read_text().splitlines()
        printed = {cells[1]: cells[3] for line in lines if (cells := line.split(" | "))[0] == "| held-out layouts"}
        for algo, row in held_out.iterrows():
            assert f"{row.iqm:.2f} [{row.iqm_ci_low:.2f}, {row.iqm_ci_high:.2f}]" == printed[algo], (folder.name, algo)
        success = pd.read_csv(folder / "success.csv")
        success = success[success["test_set"] == "held-out layouts"]
        for algo, count in held_out["runs_at_target"].items():
            assert count == (success[success["algo"] == algo]["success_rate"] >= 0.9).sum()


def test_failures_sum_the_hits_and_leave_unrecorded_grids_empty(summary_module):
    hits = {"hit_wall": [2, 0], "hit_box": [0, 0], "hit_cylinder": [1, 0], "hit_stub": [1, 0]}
    sightings = {"hit_obstacle": [2, 0], "hit_unseen": [1, 0]}
    recorded = pd.DataFrame({"episodes": [10, 10], "successes": [7, 10], **hits, **sightings})
    expected = {"failed_episodes": 3, "hit_wall": 2, "hit_box": 0, "hit_cylinder": 1, "hit_stub": 1}
    assert summary_module.failures(recorded) == expected | {"hit_obstacle": 2, "hit_unseen": 1}
    # Scored before the sightings were recorded: the hits are kept, the sightings empty.
    hits_only = summary_module.failures(recorded.drop(columns=list(sightings)))
    assert {key: hits_only[key] for key in expected} == expected
    assert all(np.isnan(hits_only[column]) for column in summary_module.SIGHTINGS)
    older = summary_module.failures(recorded[["episodes", "successes"]])
    assert older["failed_episodes"] == 3
    assert all(np.isnan(older[hit]) for hit in (*summary_module.HITS, *summary_module.SIGHTINGS))


def grid_success(rates: dict[str, list[float]], algo: str = "adc") -> pd.DataFrame:
    """A grid's ``success.csv``: runs (seeds 0, 1, ...) with these success rates per test set (10 episodes each)."""
    rows = []
    for test_set, per_run in rates.items():
        for seed, rate in enumerate(per_run):
            rows.append((algo, seed, test_set, 10, round(10 * rate), rate))
    return pd.DataFrame(rows, columns=["algo", "seed", "test_set", "episodes", "successes", "success_rate"])


def test_comparisons_set_the_runs_of_two_grids_against_each_other(summary_module, tmp_path):
    changed = {"held-out layouts": [1.0, 0.9, 0.8], "unseen_posts": [1.0, 1.0, 0.0], "unseen_wide": [1.0, 1.0, 1.0]}
    control = {"held-out layouts": [0.7, 0.6, 0.5], "unseen_posts": [0.0, 0.0, 0.0], "unseen_wide": [1.0, 1.0, 1.0]}
    for name, rates in (("changed", changed), ("control", control)):
        (tmp_path / name).mkdir()
        grid_success(rates | {"training": [1.0, 1.0, 1.0]}).to_csv(tmp_path / name / "success.csv", index=False)
    table = summary_module.compare(tmp_path, [("changed", "control"), ("changed", "absent")], reps=200)
    # The pair with a grid not committed is left out; one row per test set of the pair that is.
    assert list(table["test_set"]) == ["held-out layouts", summary_module.COURSE_FILES, "unseen_posts"]
    rows = table.set_index("test_set")
    # Every changed run beats every control run on the held-out layouts.
    assert rows.loc["held-out layouts", "probability"] == 1.0
    assert rows.loc["held-out layouts", "changed_mean"] == pytest.approx(0.9)
    # On the posts two of three changed runs beat every control run and the third ties them: (2 + 0.5) / 3.
    assert rows.loc["unseen_posts", "probability"] == pytest.approx(2.5 / 3)
    assert rows.loc["unseen_posts", "ci_low"] <= rows.loc["unseen_posts", "probability"] <= rows.loc["unseen_posts", "ci_high"]
    # The course files pooled per run without `training`: posts and wide, 20 episodes a run.
    assert rows.loc[summary_module.COURSE_FILES, "changed_mean"] == pytest.approx((1.0 + 1.0 + 0.5) / 3)
    assert rows.loc[summary_module.COURSE_FILES, "control_mean"] == pytest.approx(0.5)
    assert "P(changed > control)" in summary_module.comparisons_markdown(table)
    assert summary_module.comparisons_markdown(table.iloc[:0]) == ""


def test_a_comparison_side_picks_one_algorithm_of_a_grid_of_several(summary_module, tmp_path):
    control = {"held-out layouts": [0.5, 0.5], "unseen_posts": [0.5, 0.5]}
    (tmp_path / "control").mkdir()
    grid_success(control).to_csv(tmp_path / "control" / "success.csv", index=False)
    # A grid of two algorithms: ADC's runs better than the control's on the held-out layouts, TD3's worse.
    (tmp_path / "shipped").mkdir()
    shipped = pd.concat(
        [
            grid_success({"held-out layouts": [0.9, 0.8], "unseen_posts": [0.5, 0.5]}, "adc"),
            grid_success({"held-out layouts": [0.1, 0.2], "unseen_posts": [0.5, 0.5]}, "td3"),
        ]
    )
    shipped.to_csv(tmp_path / "shipped" / "success.csv", index=False)
    pairs = [(("shipped", "adc"), "control"), (("shipped", "td3"), "control"), (("shipped", "sac"), "control")]
    table = summary_module.compare(tmp_path, pairs, reps=200)
    # SAC is not scored in the grid (yet): its pair is left out, as a grid not committed is.
    assert list(dict.fromkeys(table["changed"])) == ["shipped (ADC)", "shipped (TD3)"]
    held_out = table[table["test_set"] == "held-out layouts"].set_index("changed")
    assert held_out.loc["shipped (ADC)", "changed_mean"] == pytest.approx(0.85)
    assert held_out.loc["shipped (ADC)", "probability"] == 1.0
    assert held_out.loc["shipped (TD3)", "probability"] == 0.0
    assert set(table["control"]) == {"control"}
    # Named by its grid alone, a grid of several algorithms would pool them: refused, naming the way to pick one.
    with pytest.raises(ValueError, match=r"'shipped' holds adc, td3: name one, as \('shipped', algo\)"):
        summary_module.compare(tmp_path, [("shipped", "control")], reps=200)
