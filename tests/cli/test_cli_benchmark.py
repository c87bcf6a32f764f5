"""``sb3-adc benchmark`` then ``sb3-adc plot`` end to end: a tiny grid in parallel processes, resumed, plotted."""

import os

import numpy as np
import pandas as pd
import pytest

from sb3_adc.experiment.results import EPISODE_COLUMNS, EVALUATION_COLUMNS, FINAL_COLUMNS


@pytest.fixture(scope="module")
def grid(tmp_path_factory, tiny_conf):
    """A 2 algorithms x 1 environment x 2 seeds grid of 200-step runs, run once for the module."""
    from sb3_adc.cli import main

    folder = tmp_path_factory.mktemp("benchmark") / "bench"
    args = ["benchmark", "--algos", "adc", "ddpg", "--envs", "Pendulum-v1", "--seeds", "0", "1", "-f", str(folder)]
    args += ["--conf-folder", str(tiny_conf), "-n", "200", "--eval-freq", "100", "--eval-episodes", "1", "--workers", "2"]
    args += ["--final-eval-episodes", "2"]
    assert main(args) == 0
    return folder, args


def test_benchmark_writes_one_tidy_csv_of_evaluation_curves(grid):
    folder, _ = grid
    curves = pd.read_csv(folder / "evaluations.csv")
    assert tuple(curves.columns) == EVALUATION_COLUMNS
    assert len(curves) == 2 * 2 * 2
    assert sorted(set(zip(curves["algo"], curves["seed"], strict=True))) == [("adc", 0), ("adc", 1), ("ddpg", 0), ("ddpg", 1)]
    assert set(curves["env"]) == {"Pendulum-v1"}
    assert sorted(set(curves["timesteps"])) == [100, 200]
    assert (curves["n_episodes"] == 1).all()
    assert (curves["min_return"] <= curves["mean_return"]).all()
    assert (curves["mean_return"] <= curves["max_return"]).all()
    episodes = pd.read_csv(folder / "episodes.csv")
    assert tuple(episodes.columns) == EPISODE_COLUMNS
    assert len(episodes) == 4 * 4
    assert list(episodes[(episodes.algo == "adc") & (episodes.seed == 1)]["timesteps"]) == [50, 100, 150, 200]
    final = pd.read_csv(folder / "final.csv")
    assert tuple(final.columns) == FINAL_COLUMNS
    assert len(final) == 4
    assert (final["timesteps"] == 200).all()
    for algo, seed in (("adc", 0), ("ddpg", 1)):
        assert os.path.isfile(folder / algo / f"Pendulum-v1_seed{seed}" / "Pendulum-v1.zip")


def test_rerunning_skips_finished_runs_and_resumes_interrupted_ones(grid, cli):
    folder, args = grid
    before = pd.read_csv(folder / "evaluations.csv")
    # Make one run look interrupted after its checkpoint at 100 steps.
    run_dir = folder / "ddpg" / "Pendulum-v1_seed0"
    for name in ("rl_model_200_steps.zip", "Pendulum-v1.zip", os.path.join("Pendulum-v1", "final_evaluation.json")):
        os.remove(run_dir / name)
    rerun = [*args[: args.index("--workers")], "--workers", "1", *args[args.index("--workers") + 2 :]]
    status, out, _ = cli(*rerun)
    assert status == 0
    assert out.count(" skipped: final return") == 3
    assert "ddpg on Pendulum-v1, seed 0 resumed" in out
    after = pd.read_csv(folder / "evaluations.csv")
    # Finished runs are untouched; the resumed run kept its first evaluation and redid the second.
    pd.testing.assert_frame_equal(after[after.algo == "adc"], before[before.algo == "adc"])
    kept = after[(after.algo == "ddpg") & (after.seed == 0)]
    assert list(kept["timesteps"]) == [100, 200]
    assert kept["mean_return"].iloc[0] == before[(before.algo == "ddpg") & (before.seed == 0)]["mean_return"].iloc[0]
    # The resumed run's training time goes on from where its first part stopped.
    episodes = pd.read_csv(folder / "episodes.csv")
    for _, run in episodes.groupby(["algo", "seed"]):
        times = run.sort_values("timesteps")["wall_time_s"].to_numpy()
        assert (times > 0).all()
        assert (np.diff(times) >= 0).all()


def test_plot_writes_figures_and_an_iqm_table(grid, cli, tmp_path):
    folder, _ = grid
    status, out, _ = cli("plot", "--csv", folder / "evaluations.csv", "-o", tmp_path / "plots", "--reps", 200)
    assert status == 0
    for name in ("learning_curves.png", "reward_variance.png", "final_performance.png"):
        assert (tmp_path / "plots" / name).stat().st_size > 10_000, name
    table = pd.read_csv(tmp_path / "plots" / "final_performance.csv")
    assert list(table["algo"]) == ["adc", "ddpg"]
    # From final.csv (found next to the evaluations): two runs each.
    final = pd.read_csv(folder / "final.csv")
    assert table["mean"].tolist() == pytest.approx(final.groupby("algo")["mean_return"].mean().tolist())
    assert "| Pendulum-v1 | adc | 2 |" in out
    assert (tmp_path / "plots" / "episode_variance.csv").is_file()


def test_benchmark_errors(cli, tmp_path):
    status, _, err = cli("benchmark", "--algos", "adc", "--envs", "Pendulum-v9", "-f", tmp_path)
    assert status == 2
    assert "unknown environment id 'Pendulum-v9'" in err
    status, _, err = cli("benchmark", "--algos", "adc", "--envs", "Pendulum-v1", "--n-seeds", 0, "-f", tmp_path)
    assert status == 2
    assert "--n-seeds must be >= 1" in err


def test_ctrl_c_ends_the_benchmark_with_status_130_and_the_resume_message(cli, tiny_conf, tmp_path, monkeypatch):
    from sb3_adc.cli import benchmark_command
    from sb3_adc.experiment.benchmark import INTERRUPTED

    def ctrl_c(*_, **__):
        raise KeyboardInterrupt

    monkeypatch.setattr(benchmark_command, "run_benchmark", ctrl_c)
    status, _, err = cli(
        "benchmark",
        "--algos",
        "adc",
        "--envs",
        "Pendulum-v1",
        "--seeds",
        "0",
        "-f",
        str(tmp_path / "bench"),
        "--conf-folder",
        str(tiny_conf),
        "-n",
        "200",
    )
    assert status == 130
    assert INTERRUPTED in err
