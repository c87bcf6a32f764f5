"""rliable statistics of benchmark tables, checked against direct computations on synthetic results."""

import numpy as np
import pandas as pd
import pytest
from scipy.stats import trim_mean

from sb3_adc.experiment.plots import plot_results
from sb3_adc.experiment.statistics import episode_variance, final_performance, learning_curves, markdown_table


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
