"""The committed budget sweeps agree with themselves and with the protocol: tuning seeds only, validation layouts
disjoint from the training and test layouts, one row per run and checkpoint, and the curves and summary rebuilt
from the per-checkpoint rows."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import pandas as pd
import pytest

from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS, TRAIN_LAYOUT_SEEDS, VALIDATION_LAYOUT_SEEDS

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results" / "budget_sweep"
FOLDERS = sorted(path.parent for path in RESULTS.glob("*/sweep.csv"))


@pytest.mark.skipif(not FOLDERS, reason="no committed budget sweep")
@pytest.mark.parametrize("folder", FOLDERS, ids=[folder.name for folder in FOLDERS])
def test_committed_sweep_follows_the_protocol_and_rebuilds(folder, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    budget_sweep = importlib.import_module("budget_sweep")
    metadata = json.loads((folder / "metadata.json").read_text())
    sweep = pd.read_csv(folder / "sweep.csv")
    # Tuning seeds only: the reporting seeds (1000+) stay unseen.
    assert set(sweep["seed"]) == set(metadata["seeds"])
    assert max(metadata["seeds"]) < 5
    # Validation layouts: after the training and held-out ranges.
    first, last = metadata["validation_layouts"]
    assert VALIDATION_LAYOUT_SEEDS[0] == first <= last < VALIDATION_LAYOUT_SEEDS[1]
    assert TRAIN_LAYOUT_SEEDS[1] <= TEST_LAYOUT_SEEDS[1] <= first
    assert (sweep["episodes"] == last - first + 1).all()
    assert (sweep["success_rate"] == sweep["successes"] / sweep["episodes"]).all()
    # One row per configuration, seed and checkpoint; the checkpoints every tenth of the budget.
    every = metadata["checkpoint_every"]
    steps = list(range(every, metadata["n_timesteps"] + 1, every))
    # Each configuration, and the actor itself of those that deploy an averaged actor (the same runs).
    itself = " (actor itself)"
    assert {config.removesuffix(itself) for config in sweep["config"]} == set(metadata["configs"])
    for config in {config.removesuffix(itself) for config in sweep["config"] if config.endswith(itself)}:
        assert "actor_average_tau" in str(metadata["configs"][config].get("policy_kwargs")), config
    for (config, seed), rows in sweep.groupby(["config", "seed"]):
        assert sorted(rows["timesteps"]) == steps, (config, seed)
    # The curves and the summary rebuild from the rows.
    rebuilt = budget_sweep.summarise(sweep, metadata["bootstrap_reps"])
    committed = pd.read_csv(folder / "curves.csv")
    pd.testing.assert_frame_equal(rebuilt, committed, check_exact=False, rtol=1e-9, check_dtype=False)
    assert (folder / "summary.md").read_text() == budget_sweep.markdown(committed)
    best = committed.loc[committed["mean"].idxmax()]
    assert metadata["best"] == {"config": best["config"], "timesteps": int(best["timesteps"]), "mean": round(best["mean"], 3)}
    for name in ("budget_sweep", "procedural_generalisation"):
        sys.modules.pop(name, None)


def test_configs_file_is_checked_and_committed_sweeps_name_theirs(tmp_path, monkeypatch):
    from sb3_adc.config.loader import HyperparamsError

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    budget_sweep = importlib.import_module("budget_sweep")
    for text, match in [
        ("[1, 2]\n", "non-empty mapping"),
        ("{}\n", "non-empty mapping"),
        ("wide: 3\n", "mapping of key: value overrides"),
        ("1: {gamma: 0.98}\n", "non-empty strings"),
    ]:
        path = tmp_path / "configs.yml"
        path.write_text(text)
        with pytest.raises(HyperparamsError, match=match):
            budget_sweep.read_configs(str(path))
    path.write_text("long horizon:\n  gamma: 0.99\n")
    assert budget_sweep.read_configs(str(path)) == {"long horizon": {"gamma": 0.99}}
    # A committed sweep from a configurations file ran that file's configurations: the file its metadata names,
    # or, for sweeps committed before the metadata named it, the file of the folder's name.
    for folder in FOLDERS:
        metadata = json.loads((folder / "metadata.json").read_text())
        named = metadata.get("configs_file")
        configs = ROOT / "benchmarks" / "configs" / "budget_sweep" / f"{folder.name.split('_', 2)[-1]}.yml"
        configs = ROOT / named if named else configs
        if named or configs.exists():
            assert metadata["configs"] == budget_sweep.read_configs(str(configs))
    sys.modules.pop("budget_sweep", None)
    sys.modules.pop("procedural_generalisation", None)


def test_the_averaged_actor_sweep_holds_the_same_runs_as_its_control():
    """The averaged actor changes nothing that is learned: the actor itself of each run of the averaged-actor sweep
    scores, checkpoint by checkpoint, what the same seed's "4 rays" run of the earlier sweep scored."""
    sweep = pd.read_csv(RESULTS / "LidarObstacleCourse-v1_adc_actor_average_150k" / "sweep.csv")
    control = pd.read_csv(RESULTS / "LidarObstacleCourse-v1_adc_sectors_batch_150k" / "sweep.csv")
    columns = ["seed", "timesteps", "episodes", "successes"]
    itself = sweep[sweep["config"] == "4 rays averaged actor (actor itself)"][columns].sort_values(columns[:2])
    same = control[control["config"] == "4 rays"][columns].sort_values(columns[:2])
    assert len(itself) == 50
    pd.testing.assert_frame_equal(itself.reset_index(drop=True), same.reset_index(drop=True))


@pytest.mark.parametrize("argv", [[], ["--configs", "CONFIGS"]], ids=["entry and gammas", "configs file"])
def test_every_configuration_overrides_the_frozen_starting_entry(tmp_path, grid_settings, argv):
    """A sweep keeps its meaning when the shipped entry changes: every configuration resolves against
    ``benchmarks/configs/starting_entries/``, with or without a configuration file."""
    from sb3_adc.config.loader import load_hyperparams, read_hyperparams_file, select_entry

    configs = tmp_path / "configs.yml"
    configs.write_text("long horizon: {gamma: 0.99}\n")
    argv = [str(configs) if arg == "CONFIGS" else arg for arg in argv]
    grids = grid_settings("budget_sweep", "run_benchmarks", ["--algo", "td3", *argv])
    env_id = "sb3_adc/LidarObstacleCourse-v1"
    path = str(ROOT / "benchmarks" / "configs" / "starting_entries" / "td3.yml")
    start, _ = select_entry(read_hyperparams_file(path), env_id, path)
    assert grids
    for settings in grids:
        run = settings.train_settings(settings.grid()[0])
        assert run.conf_file == path
        config = load_hyperparams("td3", env_id, run.conf_file, run.overrides)
        assert config.saved["batch_size"] == start["batch_size"]
        assert config.saved["gamma"] == settings.overrides.get("gamma", start["gamma"])


def test_a_checkpoint_is_the_model_of_its_step_whatever_the_budget(tmp_path, monkeypatch):
    """What a budget sweep rests on: a run's checkpoint at step k is the model any budget of k steps or more trains,
    so one run gives the whole budget curve, and a longer sweep (actor_average_300k.yml) extends the runs of a
    shorter one (actor_average_150k.yml). Checked with that configuration (3-step returns, twin critics, averaged
    actor, epsilon-gated noise, four rays, clearance shaping), tiny networks and the sweep's own grid settings, with
    the periodic evaluations and checkpoints of a budget of 100 steps against one of 200."""
    import torch as th

    from sb3_adc.adc import ADC
    from sb3_adc.experiment.benchmark import RunSpec, run_benchmarks
    from sb3_adc.experiment.layout import RunLayout

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    budget_sweep = importlib.import_module("budget_sweep")
    (overrides,) = budget_sweep.read_configs(
        str(ROOT / "benchmarks" / "configs" / "budget_sweep" / "actor_average_300k.yml")
    ).values()
    overrides = {
        **overrides,
        "learning_starts": 40,
        "batch_size": 16,
        "policy_kwargs": overrides["policy_kwargs"].replace("[100, 20]", "[8]").replace("[100]", "[8]").replace("[20]", "[4]"),
        "env_kwargs": {**overrides["env_kwargs"], "max_episode_steps": 30},
    }
    env_id, algo = "sb3_adc/LidarObstacleCourse-v1", "adc"
    budgets = (100, 200)
    grids = [
        budget_sweep.BenchmarkSettings(
            algos=[algo],
            env_ids=[env_id],
            seeds=[3],
            log_folder=str(tmp_path / f"budget_{budget}"),
            n_timesteps=budget,
            overrides=overrides,
            conf_folder=str(budget_sweep.STARTING_ENTRIES),
            eval_freq=budget // budget_sweep.N_CHECKPOINTS,
            eval_episodes=1,
            final_eval_episodes=1,
            device="cpu",
            keep_checkpoints=budget_sweep.N_CHECKPOINTS + 1,
        )
        for budget in budgets
    ]
    try:
        results = run_benchmarks(grids, workers=1)
    finally:
        sys.modules.pop("budget_sweep", None)
        sys.modules.pop("procedural_generalisation", None)
    assert not any(result.failures for result in results)
    checkpoints = [
        {
            point.timesteps: point.model
            for point in RunLayout(RunSpec(algo, env_id, 3).run_dir(grid.log_folder), env_id).checkpoints()
        }
        for grid in grids
    ]
    shared = sorted(set(checkpoints[0]) & set(checkpoints[1]))
    assert shared == [20, 40, 60, 80, 100]
    for step in shared:
        short, long = (ADC.load(points[step], device="cpu").policy.state_dict() for points in checkpoints)
        assert any(name.startswith("actor_average.") for name in short)
        assert set(short) == set(long)
        for name, tensor in short.items():
            assert th.equal(tensor, long[name]), (step, name)
