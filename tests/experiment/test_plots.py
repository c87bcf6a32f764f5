"""Benchmark figures: units, shared axes, the paper's algorithm names, performance profiles and P(X > Y)."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from sb3_adc.experiment.plots import (
    ALGO_DISPLAY_NAMES,
    display_name,
    plot_comparisons,
    plot_final_performance,
    plot_reward_variance,
)
from sb3_adc.experiment.statistics import (
    final_performance,
    learning_curves,
    performance_profiles,
    probability_of_improvement,
)


@pytest.fixture
def saved_figures(monkeypatch):
    """The figures the plot functions save, in order (they are written to disk as usual)."""
    figures: list[Figure] = []
    original = Figure.savefig

    def savefig(self, *args, **kwargs):
        figures.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return figures


def finals(returns: dict[tuple[str, str], list[float]]) -> pd.DataFrame:
    rows = [
        {"env": env, "algo": algo, "seed": seed, "mean_return": value}
        for (env, algo), values in returns.items()
        for seed, value in enumerate(values)
    ]
    return pd.DataFrame(rows)


def test_every_algorithm_of_the_cli_has_a_display_name():
    assert display_name("dqn") == "dueling DQN, 25 actions"
    assert display_name("vanilla_ac") == "vanilla actor-critic"
    assert display_name("my_algo") == "my_algo"
    assert len(set(ALGO_DISPLAY_NAMES.values())) == len(ALGO_DISPLAY_NAMES)


def test_final_performance_panels_share_one_x_range(tmp_path, saved_figures):
    table = finals(
        {
            ("Pendulum-v1", "adc"): [-150.0, -140.0, -160.0],
            ("Pendulum-v1", "dqn"): [-170.0, -180.0, -175.0],
            ("sb3_adc/NoisyPendulum-v1", "adc"): [-900.0, -1000.0, -950.0],
            ("sb3_adc/NoisyPendulum-v1", "dqn"): [-300.0, -320.0, -310.0],
        }
    )
    performance = final_performance(table, reps=200)
    plot_final_performance(performance, str(tmp_path / "final.png"))
    axes = [ax for ax in saved_figures[-1].axes if ax.get_visible()]
    assert len(axes) == 2
    assert axes[0].get_xlim() == axes[1].get_xlim()
    low, high = axes[0].get_xlim()
    assert low <= performance[["iqm_ci_low", "mean_ci_low"]].to_numpy().min()
    assert high >= performance[["iqm_ci_high", "mean_ci_high"]].to_numpy().max()
    for ax in axes:
        assert [label.get_text() for label in ax.get_yticklabels()] == ["ADC", "dueling DQN, 25 actions"]


def test_variance_axes_carry_the_unit_and_display_names(tmp_path, saved_figures):
    rng = np.random.default_rng(0)
    evaluations = pd.DataFrame(
        [
            {"env": "Pendulum-v1", "algo": algo, "seed": seed, "timesteps": step, "mean_return": rng.normal(-500, 50)}
            for algo, seed, step in itertools.product(("adc", "vanilla_ac"), range(3), (100, 200))
        ]
    )
    episodes = evaluations.rename(columns={"timesteps": "episode", "mean_return": "return"})
    plot_reward_variance(learning_curves(evaluations, reps=100), episodes, str(tmp_path / "variance.png"))
    axes = saved_figures[-1].axes
    assert len(axes) == 2
    for ax in axes:
        assert ax.get_ylabel() == "variance across runs (return²)"
        assert [text.get_text() for text in ax.get_legend().get_texts()] == ["ADC", "vanilla actor-critic"]


def test_performance_profiles_are_the_fraction_of_runs_above_each_threshold():
    returns = {
        ("Pendulum-v1", "adc"): [-150.0, -400.0, -160.0, -1200.0],
        ("Pendulum-v1", "ddpg"): [-900.0, -140.0, -800.0, -700.0],
    }
    profiles = performance_profiles(finals(returns), n_taus=21, reps=200)
    assert set(profiles["algo"]) == {"adc", "ddpg"}
    for (env, algo), values in returns.items():
        profile = profiles[(profiles["env"] == env) & (profiles["algo"] == algo)]
        taus = profile["tau"].to_numpy()
        assert len(taus) == 21
        # One threshold axis per environment, spanning every algorithm's returns.
        assert taus[0] < -1200.0
        assert taus[-1] == -140.0
        expected = (np.asarray(values)[:, None] > taus).mean(axis=0)
        np.testing.assert_allclose(profile["fraction"], expected)
        assert profile["fraction"].iloc[0] == 1.0
        assert np.all(np.diff(profile["fraction"]) <= 0)
        assert np.all(profile["fraction_ci_low"] <= profile["fraction"] + 1e-12)
        assert np.all(profile["fraction"] <= profile["fraction_ci_high"] + 1e-12)
    with pytest.raises(ValueError, match="n_taus must be >= 2"):
        performance_profiles(finals(returns), n_taus=1)


def test_probability_of_improvement_counts_wins_over_environments():
    returns = {
        ("Pendulum-v1", "adc"): [-150.0, -160.0, -170.0],
        ("Pendulum-v1", "ddpg"): [-155.0, -400.0, -500.0],
        ("Pendulum-v1", "dqn"): [-100.0, -110.0, -120.0],
        ("sb3_adc/NoisyPendulum-v1", "adc"): [-200.0, -210.0, -220.0],
        ("sb3_adc/NoisyPendulum-v1", "ddpg"): [-100.0, -300.0, -205.0],
    }
    table = probability_of_improvement(finals(returns), reps=300)
    # Each pair once, with ADC as X.
    assert list(zip(table.algo_x, table.algo_y, strict=True)) == [("adc", "ddpg"), ("adc", "dqn"), ("ddpg", "dqn")]

    def direct(x, y):
        x, y = np.asarray(x)[:, None], np.asarray(y)[None, :]
        return float(np.mean((x > y) + 0.5 * (x == y)))

    adc_ddpg = table.iloc[0]
    expected = np.mean(
        [direct(returns[(env, "adc")], returns[(env, "ddpg")]) for env in ("Pendulum-v1", "sb3_adc/NoisyPendulum-v1")]
    )
    assert adc_ddpg.n_envs == 2
    assert adc_ddpg.probability == pytest.approx(expected)
    assert adc_ddpg.ci_low <= adc_ddpg.probability <= adc_ddpg.ci_high
    # The dueling DQN beats ADC in every run: P = 0, with a degenerate interval; only one environment shared.
    adc_dqn = table.iloc[1]
    assert (adc_dqn.n_envs, adc_dqn.probability, adc_dqn.ci_low, adc_dqn.ci_high) == (1, 0.0, 0.0, 0.0)


def test_sb3_adc_plot_writes_profiles_and_probability_of_improvement(tmp_path, capsys):
    from sb3_adc.cli import main

    rng = np.random.default_rng(1)
    rows = [
        {
            "algo": algo,
            "env": "Pendulum-v1",
            "seed": seed,
            "timesteps": step,
            "mean_return": rng.normal(offset, 30),
            "std_return": 1.0,
            "n_episodes": 5,
        }
        for (algo, offset), seed, step in itertools.product((("adc", -300), ("dqn", -600)), range(3), (500, 1000))
    ]
    csv = tmp_path / "evaluations.csv"
    pd.DataFrame(rows).to_csv(csv, index=False)
    assert main(["plot", "--csv", str(csv), "--reps", "100"]) == 0
    plots = tmp_path / "plots"
    for name in ("performance_profiles.png", "probability_of_improvement.png", "final_performance.png"):
        assert (plots / name).stat().st_size > 10_000
    improvement = pd.read_csv(plots / "probability_of_improvement.csv")
    assert list(zip(improvement.algo_x, improvement.algo_y, strict=True)) == [("adc", "dqn")]
    assert improvement.probability.iloc[0] == pytest.approx(1.0)
    assert "probability_of_improvement.png" in capsys.readouterr().out
    with pytest.raises(ValueError, match="no final returns"):
        plot_comparisons(pd.DataFrame(columns=["env", "algo", "seed", "mean_return"]), str(tmp_path))
