"""rliable statistics of benchmark tables, checked against direct computations on synthetic results."""

import numpy as np
import pandas as pd
import pytest
from scipy.stats import trim_mean

from sb3_adc.experiment.plots import plot_results
from sb3_adc.experiment.results import read_table, training_seconds
from sb3_adc.experiment.statistics import (
    episode_variance,
    evaluation_times,
    final_performance,
    iqm,
    learning_curves,
    markdown_table,
    probability_of_improvement_metric,
    time_to_threshold,
    wallclock_curves,
)


def synthetic_evaluations(n_seeds=6, steps=(100, 200, 300, 400)):
    rng = np.random.default_rng(0)
    rows = []
    for env, offset in (("Pendulum-v1", 0.0), ("sb3_adc/NoisyPendulum-v1", -100.0)):
        for algo, spread in (("adc", 10.0), ("ddpg", 60.0)):
            for seed in range(n_seeds):
                for index, step in enumerate(steps):
                    value = offset - 1000 + 200 * index + rng.normal(0, spread)
                    rows.append({"algo": algo, "env": env, "seed": seed, "timesteps": step, "mean_return": value})
    return pd.DataFrame(rows)


def test_final_performance_iqm_and_mean_with_cis():
    final = synthetic_evaluations().query("timesteps == 400")
    table = final_performance(final, reps=500)
    assert list(zip(table.env, table.algo, strict=True)) == [
        ("Pendulum-v1", "adc"),
        ("Pendulum-v1", "ddpg"),
        ("sb3_adc/NoisyPendulum-v1", "adc"),
        ("sb3_adc/NoisyPendulum-v1", "ddpg"),
    ]
    for row in table.itertuples():
        scores = final[(final.env == row.env) & (final.algo == row.algo)]["mean_return"].to_numpy()
        assert row.n_runs == 6
        assert row.mean == pytest.approx(scores.mean())
        assert row.iqm == pytest.approx(trim_mean(scores, 0.25))
        assert row.mean_ci_low < row.mean < row.mean_ci_high
        assert row.iqm_ci_low <= row.iqm <= row.iqm_ci_high
        assert scores.min() <= row.mean_ci_low
        assert row.mean_ci_high <= scores.max()
    # The spread of DDPG's synthetic runs is 6x ADC's: so is the width of its CI, roughly.
    widths = (table.mean_ci_high - table.mean_ci_low).to_numpy()
    assert widths[1] > 3 * widths[0]
    markdown = markdown_table(table)
    assert markdown.splitlines()[0] == "| Environment | Algorithm | Runs | IQM [95% CI] | Mean [95% CI] |"
    assert f"| Pendulum-v1 | adc | 6 | {table.iqm[0]:.1f} [" in markdown


@pytest.mark.parametrize("shape", [(1, 1), (3, 1), (4, 1), (10, 1), (7, 3), (10, 4)])
def test_the_numpy_metrics_equal_rliables(shape):
    """The bootstrap's IQM and probability of improvement give rliable's numbers, with ties and rounded scores."""
    rliable = pytest.importorskip("rliable.metrics")
    rng = np.random.default_rng(sum(shape))
    for rounding in (None, 0):
        x, y = rng.normal(0, 2, shape), rng.normal(0.5, 2, (shape[0] + 2, shape[1]))
        if rounding is not None:  # ties inside and across the two samples
            x, y = np.round(x, rounding), np.round(y, rounding)
        assert iqm(x) == rliable.aggregate_iqm(x)
        np.testing.assert_array_equal(iqm(x, axis=0), trim_mean(x, 0.25, axis=0))
        for pair in ((x, y), (y, x), (x, x)):
            assert probability_of_improvement_metric(*pair) == rliable.probability_of_improvement(*pair)


def test_intervals_are_reproducible_and_leave_numpy_alone():
    final = synthetic_evaluations().query("timesteps == 400")
    np.random.seed(123)
    expected_draw = np.random.random()
    np.random.seed(123)
    first = final_performance(final, reps=300, seed=7)
    assert np.random.random() == expected_draw
    pd.testing.assert_frame_equal(first, final_performance(final, reps=300, seed=7))
    other = final_performance(final, reps=300, seed=8)
    assert not np.allclose(other["mean_ci_low"], first["mean_ci_low"])


def test_learning_curves_mean_and_across_run_variance():
    evaluations = synthetic_evaluations()
    # A run missing an evaluation: that timestep is dropped for its (env, algo) only.
    evaluations = evaluations.drop(evaluations.index[(evaluations.algo == "ddpg") & (evaluations.seed == 0)][-1:])
    curves = learning_curves(evaluations, reps=300)
    adc = curves[(curves.env == "Pendulum-v1") & (curves.algo == "adc")]
    assert list(adc.timesteps) == [100, 200, 300, 400]
    ddpg = curves[(curves.env == "sb3_adc/NoisyPendulum-v1") & (curves.algo == "ddpg")]
    assert list(ddpg.timesteps) == [100, 200, 300]
    for row in adc.itertuples():
        values = evaluations[(evaluations.env == "Pendulum-v1") & (evaluations.algo == "adc")]
        values = values[values.timesteps == row.timesteps]["mean_return"].to_numpy()
        assert row.mean == pytest.approx(values.mean())
        assert row.iqm == pytest.approx(trim_mean(values, 0.25))
        assert row.variance == pytest.approx(values.var(ddof=1))
        assert row.mean_ci_low <= row.mean <= row.mean_ci_high
        assert row.variance_ci_low <= row.variance <= row.variance_ci_high
    # DDPG's synthetic runs vary more than ADC's at every timestep.
    pendulum = curves[curves.env == "Pendulum-v1"]
    assert (pendulum[pendulum.algo == "ddpg"].variance.to_numpy() > pendulum[pendulum.algo == "adc"].variance.to_numpy()).all()


def test_single_run_has_a_degenerate_ci_and_no_variance():
    one = synthetic_evaluations(n_seeds=1)
    curves = learning_curves(one, reps=100)
    assert (curves["mean_ci_low"] == curves["mean"]).all()
    assert curves["variance"].isna().all()
    table = final_performance(one.query("timesteps == 400"), reps=100)
    assert (table["n_runs"] == 1).all()
    assert (table["iqm"] == table["mean"]).all()


def test_episode_variance_per_episode_index():
    episodes = pd.DataFrame(
        {
            "algo": ["adc"] * 6,
            "env": ["Pendulum-v1"] * 6,
            "seed": [0, 0, 0, 1, 1, 1],
            "episode": [1, 2, 3, 1, 2, 3],
            "return": [-10.0, -20.0, -30.0, -14.0, -20.0, -50.0],
        }
    )
    table = episode_variance(episodes, window=2)
    assert table["variance"].tolist() == pytest.approx([8.0, 0.0, 200.0])
    assert table["variance_smoothed"].tolist() == pytest.approx([8.0, 4.0, 100.0])


def test_plot_results_writes_every_output(tmp_path):
    outputs = plot_results(synthetic_evaluations(), str(tmp_path), reps=100)
    names = sorted(path.rsplit("/", 1)[1] for path in outputs.figures + outputs.tables)
    assert names == sorted(
        [
            "learning_curves.png",
            "reward_variance.png",
            "final_performance.png",
            "curves.csv",
            "final_performance.csv",
            "final_performance.md",
        ]
    )
    for path in outputs.figures:
        assert (tmp_path / path.rsplit("/", 1)[1]).stat().st_size > 10_000
    with pytest.raises(ValueError, match="no evaluations to plot"):
        plot_results(synthetic_evaluations().iloc[:0], str(tmp_path))


@pytest.mark.parametrize("name", ["table.csv", "table.csv.gz"])
def test_tables_are_read_back_with_the_floats_written(tmp_path, name):
    """A statistic computed from a table read back prints as it printed when the table was written: 0.925 read
    for 0.9249999999999999 (pandas' default parser) moves a two-decimal IQM from 0.92 to 0.93."""
    rates = [0.9249999999999999, 0.1 + 0.2, 1 / 3, 2.675]
    pd.DataFrame({"algo": "adc", "seed": range(4), "success_rate": rates}).to_csv(tmp_path / name, index=False)
    table = read_table(tmp_path / name)
    assert table["success_rate"].tolist() == rates
    assert table["seed"].tolist() == [0, 1, 2, 3]


def test_training_seconds_continue_across_a_resume():
    # The monitor's clock restarts at zero when a run resumes: later episodes continue from the last one before.
    assert training_seconds(np.array([1.0, 2.0, 3.0, 0.5, 1.5, 0.2])).tolist() == pytest.approx([1, 2, 3, 3.5, 4.5, 4.7])
    assert training_seconds(np.array([])).size == 0


def timed_runs():
    """Two algorithms, two seeds: 'slow' takes twice as long per step as 'fast', with the same evaluations."""
    evaluations, episodes = [], []
    for algo, seconds_per_step in (("fast", 0.01), ("slow", 0.02)):
        for seed in (0, 1):
            for step in (100, 200, 300, 400):
                value = -400.0 + step + 10 * seed
                evaluations.append({"algo": algo, "env": "E", "seed": seed, "timesteps": step, "mean_return": value})
                episodes.append(
                    {"algo": algo, "env": "E", "seed": seed, "timesteps": step, "wall_time_s": step * seconds_per_step}
                )
    return pd.DataFrame(evaluations), pd.DataFrame(episodes)


def test_evaluations_are_placed_at_the_time_their_run_reached_them():
    evaluations, episodes = timed_runs()
    # An evaluation between episode ends is interpolated; before the first end, from zero seconds at zero steps.
    episodes = episodes[episodes.timesteps != 200]
    timed = evaluation_times(evaluations, episodes)
    slow = timed[(timed.algo == "slow") & (timed.seed == 0)]
    assert slow["wall_time_s"].tolist() == pytest.approx([2.0, 4.0, 6.0, 8.0])
    # A run without times is left out.
    assert evaluation_times(evaluations, episodes[episodes.algo == "fast"])["algo"].unique().tolist() == ["fast"]


def test_wallclock_curves_hold_the_latest_evaluation_of_every_run():
    evaluations, episodes = timed_runs()
    curves = wallclock_curves(evaluations, episodes, n_points=4, reps=100)
    fast = curves[curves.algo == "fast"]
    slow = curves[curves.algo == "slow"]
    # From the first to the last evaluation of the runs: 1 to 4 s for the fast one, 2 to 8 s for the slow one.
    assert fast["wall_time_s"].tolist() == pytest.approx([1.0, 2.0, 3.0, 4.0])
    assert slow["wall_time_s"].tolist() == pytest.approx([2.0, 4.0, 6.0, 8.0])
    # The mean of the two seeds' latest returns: the same returns, reached twice as late by the slow algorithm.
    assert fast["mean"].tolist() == pytest.approx([-295.0, -195.0, -95.0, 5.0])
    assert slow["mean"].tolist() == pytest.approx(fast["mean"].tolist())
    assert (curves["mean_ci_low"] <= curves["mean"]).all()
    assert (curves["mean"] <= curves["mean_ci_high"]).all()
    # At 3 s the slow runs have only their first evaluation (made at 2 s).
    at_three = wallclock_curves(evaluations, episodes, n_points=7, reps=100)
    point = at_three[(at_three.algo == "slow") & np.isclose(at_three.wall_time_s, 3.0)]
    assert point["mean"].tolist() == pytest.approx([-295.0])
    with pytest.raises(ValueError, match="n_points must be >= 2"):
        wallclock_curves(evaluations, episodes, n_points=1)


def test_plot_results_adds_the_wallclock_curves_when_episodes_are_timed(tmp_path):
    evaluations, episodes = timed_runs()
    episodes["episode"], episodes["return"] = 1, -1.0
    outputs = plot_results(evaluations, str(tmp_path), episodes=episodes, reps=100)
    names = {path.rsplit("/", 1)[1] for path in outputs.figures + outputs.tables}
    assert {"wallclock_curves.png", "wallclock_curves.csv"} <= names
    assert (tmp_path / "wallclock_curves.png").stat().st_size > 10_000
    untimed = plot_results(evaluations, str(tmp_path / "untimed"), episodes=episodes.drop(columns="wall_time_s"), reps=100)
    assert not any("wallclock" in path for path in untimed.figures)


def test_time_to_threshold_is_the_first_evaluation_after_which_the_return_stays_above():
    evaluations = pd.DataFrame(
        {
            "env": "E",
            "algo": ["a"] * 4 + ["b"] * 4,
            "seed": 0,
            "timesteps": [100, 200, 300, 400] * 2,
            # a: above at 200, dips at 300, above again from 400; b: ends below.
            "mean_return": [-500.0, -100.0, -400.0, -150.0, -100.0, -100.0, -100.0, -350.0],
        }
    )
    episodes = pd.DataFrame({"env": "E", "algo": ["a"] * 8 + ["b"] * 8, "seed": 0, "timesteps": list(range(50, 450, 50)) * 2})
    table = time_to_threshold(evaluations, episodes, threshold=-200.0).set_index("algo")
    assert bool(table.loc["a", "reached"])
    assert table.loc["a", "timesteps"] == 400
    assert table.loc["a", "episodes"] == 8
    assert not bool(table.loc["b", "reached"])
    assert np.isnan(table.loc["b", "episodes"])
    assert table.loc["b", "budget_episodes"] == 8
    # Above from the first evaluation on: reached at the first one.
    assert time_to_threshold(evaluations, episodes, threshold=-1000.0)["timesteps"].tolist() == [100, 100]
