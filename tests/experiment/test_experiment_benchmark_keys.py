"""Benchmark runs on disk are reused only with the settings they were made with, and their rows are never dropped."""

import os
import re
from pathlib import Path

import pandas as pd
import pytest

from sb3_adc.cli import main
from sb3_adc.experiment.benchmark import (
    BenchmarkSettings,
    RunSettingsMismatch,
    RunSpec,
    check_runs_on_disk,
    run_benchmark,
    run_benchmarks,
    runs_on_disk,
)
from sb3_adc.experiment.layout import RunLayout


@pytest.fixture(scope="module")
def bench(tmp_path_factory, tiny_conf):
    """A finished grid of ddpg on Pendulum-v1 with seeds 0 and 1 (100 steps each) and the command that made it."""
    folder = tmp_path_factory.mktemp("bench")
    args = ["benchmark", "--algos", "ddpg", "--envs", "Pendulum-v1", "-f", str(folder / "logs"), "--workers", "1"]
    args += ["--conf-folder", str(tiny_conf), "--eval-freq", "50", "--eval-episodes", "1", "--final-eval-episodes", "1"]
    assert main([*args, "--seeds", "0", "1"]) == 0
    return folder / "logs", args


def snapshot(folder):
    return {
        os.path.join(root, name): os.stat(os.path.join(root, name)).st_mtime_ns
        for root, _, names in os.walk(folder)
        for name in names
    }


@pytest.mark.parametrize(
    ("extra", "difference"),
    [
        (["-n", "150"], "n_timesteps: 100 -> 150"),
        (["-params", "gamma:0.5"], "gamma: 0.9 -> 0.5"),
        (["--eval-episodes", "2"], "eval_episodes: 1 -> 2"),
    ],
)
def test_a_rerun_with_other_settings_is_refused_naming_the_keys(bench, capsys, extra, difference):
    folder, args = bench
    before = snapshot(folder)
    assert main([*args, "--seeds", "0", "1", *extra]) == 2  # a repeated option: argparse keeps the last
    err = capsys.readouterr().err
    assert "2 run(s) on disk were made with other settings than this benchmark asks for" in err
    for seed in (0, 1):
        assert f"{folder / 'ddpg' / f'Pendulum-v1_seed{seed}'}: {difference}" in err
    # Refused before anything ran or was written.
    assert snapshot(folder) == before


def test_a_smaller_grid_keeps_the_rows_of_the_other_runs(bench, capsys):
    folder, args = bench
    before = {name: pd.read_csv(folder / name) for name in ("evaluations.csv", "episodes.csv", "final.csv")}
    assert main([*args, "--seeds", "1"]) == 0
    assert "seed 1 skipped" in capsys.readouterr().out
    for name, table in before.items():
        after = pd.read_csv(folder / name)
        assert sorted(set(after["seed"])) == [0, 1], name
        pd.testing.assert_frame_equal(after, table)


def test_the_same_settings_pass_the_check_and_runs_on_disk_are_found(bench, tiny_conf):
    folder, _ = bench
    settings = BenchmarkSettings(
        algos=["ddpg"],
        env_ids=["Pendulum-v1"],
        seeds=[0, 1, 2],
        log_folder=str(folder),
        conf_folder=str(tiny_conf),
        eval_freq=50,
        eval_episodes=1,
        final_eval_episodes=1,
        device="cuda",  # the device does not change what a run is
    )
    check_runs_on_disk(settings)
    assert [(spec.algo, spec.env_id, spec.seed) for spec in runs_on_disk(str(folder))] == [
        ("ddpg", "Pendulum-v1", 0),
        ("ddpg", "Pendulum-v1", 1),
    ]
    settings.seeds = [1]
    settings.overrides = {"gamma": 0.5}
    with pytest.raises(RunSettingsMismatch) as info:
        check_runs_on_disk(settings)
    assert list(info.value.differences) == [str(folder / "ddpg" / "Pendulum-v1_seed1")]


def test_keep_checkpoints_keeps_every_checkpoint_and_does_not_change_what_a_run_is(bench, tmp_path, tiny_conf):
    folder, _ = bench
    settings = BenchmarkSettings(
        algos=["ddpg"],
        env_ids=["Pendulum-v1"],
        seeds=[0],
        log_folder=str(folder),
        conf_folder=str(tiny_conf),
        eval_freq=50,
        eval_episodes=1,
        final_eval_episodes=1,
        keep_checkpoints=4,
    )
    check_runs_on_disk(settings)  # the runs on disk kept 2 checkpoints: the same runs
    settings.log_folder, settings.eval_freq, settings.seeds = str(tmp_path), 25, [3]
    run_benchmark(settings, workers=1)
    run_dir = RunSpec("ddpg", "Pendulum-v1", 3).run_dir(str(tmp_path))
    steps = [point.timesteps for point in RunLayout(run_dir, "Pendulum-v1").checkpoints()]
    assert steps == [25, 50, 75, 100]
    assert len(RunLayout(RunSpec("ddpg", "Pendulum-v1", 0).run_dir(str(folder)), "Pendulum-v1").checkpoints()) == 2


def test_grids_sharing_one_pool_keep_their_own_settings_and_tables(tmp_path, tiny_conf):
    conf = str(tiny_conf)
    grids = [
        BenchmarkSettings(
            algos=["ddpg"],
            env_ids=["Pendulum-v1"],
            seeds=seeds,
            log_folder=str(tmp_path / name),
            overrides=overrides,
            conf_folder=conf,
            eval_freq=50,
            eval_episodes=1,
            final_eval_episodes=1,
        )
        for name, seeds, overrides in [("base", [0, 1], {}), ("short", [0], {"gamma": 0.5})]
    ]
    reports = []
    results = run_benchmarks(grids, workers=2, report=lambda outcome, done, total: reports.append((done, total)))
    assert reports == [(1, 3), (2, 3), (3, 3)]
    assert [sorted(outcome.spec.seed for outcome in result.outcomes) for result in results] == [[0, 1], [0]]
    assert all(outcome.status == "trained" for result in results for outcome in result.outcomes)
    assert [{outcome.log_folder for outcome in result.outcomes} for result in results] == [{g.log_folder} for g in grids]
    # Each run has its grid's overrides, and each grid's tables hold its own runs only.
    for grid, gamma in zip(grids, (0.9, 0.5), strict=True):
        saved = RunLayout(RunSpec("ddpg", "Pendulum-v1", 0).run_dir(grid.log_folder), "Pendulum-v1").config
        assert f"gamma: {gamma}" in Path(saved).read_text()
        assert sorted(set(pd.read_csv(os.path.join(grid.log_folder, "final.csv"))["seed"])) == grid.seeds
    # A grid of this pool on the first grid's folder would mix their runs: refused before anything runs.
    grids[1].log_folder = grids[0].log_folder + os.sep
    with pytest.raises(ValueError, match="its own `log_folder`"):
        run_benchmarks(grids, workers=1)
    # Every grid's runs on disk are checked before any grid runs (the first one's new seed 2 is not trained).
    grids[0].seeds = [0, 1, 2]
    grids[1].log_folder, grids[1].overrides = str(tmp_path / "short"), {"gamma": 0.7}
    before = snapshot(tmp_path)
    with pytest.raises(RunSettingsMismatch, match=re.escape("gamma: 0.5 -> 0.7")):
        run_benchmarks([grids[0], grids[1]], workers=1)
    assert snapshot(tmp_path) == before
