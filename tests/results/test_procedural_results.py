"""The committed procedural-generalisation results agree with themselves and with the environment: the drawn paths
belong to the scored runs, start at each held-out layout's start pose, and last as long as their outcome allows."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results" / "procedural_generalisation"
FOLDERS = sorted(path.parent for path in RESULTS.glob("*/trajectories.csv.gz"))
#: Steps of an episode that ends without a collision (the environment's time limit).
EPISODE_STEPS = 500
#: The environment whose shipped entries the studies measured.
V1 = "sb3_adc/LidarObstacleCourse-v1"


@pytest.mark.skipif(not FOLDERS, reason="no committed trajectories")
@pytest.mark.parametrize("folder", FOLDERS, ids=[folder.name for folder in FOLDERS])
def test_committed_paths_match_the_scored_runs_and_the_layouts(folder):
    import gymnasium as gym

    import sb3_adc  # noqa: F401 (registers the environments)

    metadata = json.loads((folder / "metadata.json").read_text())
    scores = pd.read_csv(folder / "success.csv")
    trajectories = pd.read_csv(folder / "trajectories.csv.gz")
    held_out = scores[scores["test_set"] == "held-out layouts"]
    runs = set(trajectories[["algo", "seed"]].itertuples(index=False, name=None))
    assert runs == set(held_out[["algo", "seed"]].itertuples(index=False, name=None))
    assert len(runs) == len(metadata["algos"]) * len(metadata["seeds"])
    layouts = [f"layout {TEST_LAYOUT_SEEDS[0] + k}" for k in range(metadata["trajectory_layouts"])]
    assert sorted(trajectories["course"].unique()) == layouts
    robot = {} if metadata["robot"] == "kinematic" else {"robot": metadata["robot"]}
    for name, on_layout in trajectories.groupby("course"):
        env = gym.make(metadata["env"], layout_seeds=TEST_LAYOUT_SEEDS, **robot)
        env.reset(options={"layout_seed": int(name.split()[-1])})
        start = env.unwrapped.course.start
        env.close()
        for (algo, seed), path in on_layout.groupby(["algo", "seed"]):
            path = path.sort_values("step")
            assert np.allclose(path[["x", "y"]].iloc[0], [start.x, start.y], atol=1e-3), (algo, seed, name)
            success = bool(path["success"].iloc[0])
            # A collision-free episode lasts the full time limit (its path: the start and one position a step); a
            # collision ends it at the latest on the last step.
            assert len(path) == EPISODE_STEPS + 1 if success else len(path) <= EPISODE_STEPS + 1, (algo, seed, name)
    # Every run's successes on the drawn layouts are at most its successes on all held-out layouts.
    drawn = trajectories.groupby(["algo", "seed", "course"])["success"].first().groupby(["algo", "seed"]).sum()
    for row in held_out.itertuples(index=False):
        assert drawn.loc[(row.algo, row.seed)] <= row.successes


def test_committed_pending_runs_are_those_the_metadata_names_and_stay_out_of_the_statistics():
    """A grid committed while it trains over several sessions: ``pending/`` holds exactly the runs that
    ``metadata.json`` names as ``pending_runs``, each with its scores, final evaluation and paths, of algorithms
    with a recorded entry and no rows in the grid's statistics."""
    grids = [path.parent for path in RESULTS.glob("*/metadata.json")]
    pending = {grid: json.loads((grid / "metadata.json").read_text()).get("pending_runs") for grid in grids}
    for grid in grids:
        assert bool(pending[grid]) == (grid / "pending").is_dir(), grid.name
    for grid, runs in pending.items():
        if not runs:
            continue
        metadata = json.loads((grid / "metadata.json").read_text())
        expected = {(algo, seed) for algo, seeds in runs.items() for seed in seeds}
        for name in ("success.csv", "final.csv", "trajectories.csv.gz"):
            table = pd.read_csv(grid / "pending" / name)
            assert set(table[["algo", "seed"]].itertuples(index=False, name=None)) == expected, (grid.name, name)
        # ``algos``: the algorithms in the statistics, none while a grid's first algorithm is still training.
        complete = set(metadata.get("algos", []))
        assert set(runs) <= set(metadata["entries"]) - complete
        for name in ("success.csv", "success_rates.csv"):
            if complete:
                assert not set(runs) & set(pd.read_csv(grid / name)["algo"]), (grid.name, name)
            else:
                assert not (grid / name).exists(), (grid.name, name)


PLANNER_CSV = RESULTS / "reference_planner.csv"


@pytest.mark.skipif(not PLANNER_CSV.exists(), reason="no committed reference-planner scores")
def test_committed_reference_planner_was_chosen_on_validation_and_rebuilds(monkeypatch):
    import importlib
    import sys

    from sb3_adc_envs.lidar_course.env import VALIDATION_LAYOUT_SEEDS

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    reference_planner = importlib.import_module("reference_planner")
    metadata = json.loads((RESULTS / "reference_planner_metadata.json").read_text())
    selection = pd.read_csv(RESULTS / "reference_planner_selection.csv")
    # Chosen on the validation layouts: the first setting of the grid with the highest success there.
    first, last = metadata["validation_layouts"]
    assert VALIDATION_LAYOUT_SEEDS[0] == first <= last < VALIDATION_LAYOUT_SEEDS[1]
    assert (selection["episodes"] == last - first + 1).all()
    params = list(metadata["grid"])
    assert len(selection) == np.prod([len(values) for values in metadata["grid"].values()])
    best = selection.iloc[int(selection["success_rate"].to_numpy().argmax())]
    assert {name: best[name] for name in params} == metadata["chosen"]
    # Scored on the test sets of the learned policies: every held-out layout, every course file, each variant.
    scores = pd.read_csv(PLANNER_CSV)
    courses = sorted(path.stem for path in (ROOT / "envs" / "courses").glob("*.yml"))
    assert metadata["courses"] == courses
    n_layouts = TEST_LAYOUT_SEEDS[1] - TEST_LAYOUT_SEEDS[0]
    assert metadata["held_out_layouts"] == [TEST_LAYOUT_SEEDS[0], TEST_LAYOUT_SEEDS[1] - 1]
    variants = [tuple(variant) for variant in reference_planner.VARIANTS]
    variant_columns = ["env", "robot", "rays_per_reading"]
    assert list(dict.fromkeys(scores[variant_columns].itertuples(index=False, name=None))) == variants
    for _, frame in scores.groupby(variant_columns):
        assert list(frame["test_set"]) == ["held-out layouts", *courses]
        assert list(frame["episodes"]) == [n_layouts] + [metadata["course_episodes"]] * len(courses)
    assert (scores["success_rate"] == scores["successes"] / scores["episodes"]).all()
    assert (RESULTS / "reference_planner.md").read_text() == reference_planner.markdown(scores)
    for name in ("reference_planner", "procedural_generalisation"):
        sys.modules.pop(name, None)


@pytest.mark.parametrize(
    ("text", "extra", "message"),
    [
        ("dqn: {gamma: 0.98}\n", [], "dqn not among the algorithms"),
        ("adc: 3\n", [], "mapping of key: value overrides"),
        ("adc: {gamma: 0.98}\n", ["--algos", "td3"], "--algos: td3 not in"),
    ],
)
def test_configs_file_is_checked_before_anything_runs(tmp_path, monkeypatch, capsys, text, extra, message):
    import importlib
    import sys

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    procedural_generalisation = importlib.import_module("procedural_generalisation")
    monkeypatch.setattr(procedural_generalisation, "RUNS_DIR", tmp_path / "runs")
    monkeypatch.setattr(procedural_generalisation, "RESULTS_DIR", tmp_path / "results")
    path = tmp_path / "configs.yml"
    path.write_text(text)
    monkeypatch.setattr(sys, "argv", ["procedural_generalisation.py", "--configs", str(path), *extra])
    with pytest.raises(SystemExit) as exit_info:
        procedural_generalisation.main()
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()
    assert not (tmp_path / "results").exists()
    sys.modules.pop("procedural_generalisation", None)


def _procedural_settings(grid_settings, argv):
    """The grid settings ``procedural_generalisation.py`` trains with for ``argv``, stopped before any training."""
    (settings,) = grid_settings("procedural_generalisation", "run_benchmark", argv)
    return settings


def test_algos_trains_a_subset_of_a_configs_file_with_its_overrides(tmp_path, grid_settings):
    path = tmp_path / "configs.yml"
    path.write_text("adc: {gamma: 0.95}\nddpg: {gamma: 0.97}\ntd3: {gamma: 0.96, n_timesteps: 1000}\n")
    settings = _procedural_settings(grid_settings, ["--configs", str(path), "--algos", "td3"])
    assert settings.algos == ["td3"]
    assert settings.n_timesteps == 1000
    assert settings.overrides["gamma"] == 0.96
    assert settings.log_folder == str(tmp_path / "runs" / "LidarObstacleCourse-v1_configs" / "td3")


@pytest.mark.parametrize("robot", ["kinematic", "wheeled"])
def test_configs_files_override_the_frozen_starting_entries_not_the_shipped_ones(tmp_path, monkeypatch, grid_settings, robot):
    """A configuration file keeps its meaning when a shipped entry changes: ``--configs`` runs resolve their
    overrides against ``benchmarks/configs/starting_entries/``, runs without it against ``hyperparams/``."""
    import yaml

    from sb3_adc.config import loader

    starting = ROOT / "benchmarks" / "configs" / "starting_entries"
    # The shipped entry changes after the studies began: a batch size and a sensor of its own.
    shipped = loader.read_hyperparams_file(loader.packaged_hyperparams_file("td3"))
    shipped[V1] = {**shipped[V1], "batch_size": 512, "env_kwargs": {"rays_per_reading": 4}}
    changed = tmp_path / "td3.yml"
    changed.write_text(yaml.safe_dump(shipped))
    packaged = loader.packaged_hyperparams_file
    monkeypatch.setattr(loader, "packaged_hyperparams_file", lambda name: str(changed) if name == "td3" else packaged(name))

    def resolved(settings):
        run = settings.train_settings(settings.grid()[0])
        return loader.load_hyperparams("td3", V1, run.conf_file, run.overrides)

    configs = tmp_path / "configs.yml"
    configs.write_text("td3: {gamma: 0.96}\n")
    settings = _procedural_settings(grid_settings, ["--configs", str(configs), "--robot", robot])
    assert settings.conf_folder == str(starting)
    config = resolved(settings)
    assert config.saved["gamma"] == 0.96
    assert config.saved["batch_size"] == 64  # the starting entry's, not the changed shipped one's
    assert "rays_per_reading" not in config.env_kwargs
    assert config.env_kwargs.get("robot", "kinematic") == robot
    # Without a configuration file the grid trains the shipped entries as they are.
    shipped_grid = _procedural_settings(grid_settings, ["--algos", "td3", "--robot", robot])
    assert shipped_grid.conf_folder is None
    config = resolved(shipped_grid)
    assert config.saved["batch_size"] == 512
    assert config.env_kwargs["rays_per_reading"] == 4


def test_committed_results_of_a_configs_file_ran_its_configurations():
    from sb3_adc.config.loader import read_yaml_file

    for folder in FOLDERS:
        metadata = json.loads((folder / "metadata.json").read_text())
        if "configs" not in metadata:
            continue
        configs = read_yaml_file(str(ROOT / metadata["hyperparams"].rsplit(" ", 1)[-1]))
        # ``--algos`` may train a subset of the file's algorithms, in the file's order, each with its configuration.
        assert metadata["algos"] == [algo for algo in configs if algo in metadata["algos"]]
        configs = {algo: configs[algo] for algo in metadata["algos"]}
        budgets = {algo: overrides.pop("n_timesteps", "the entry's n_timesteps") for algo, overrides in configs.items()}
        assert metadata["configs"] == configs
        assert metadata["n_timesteps"] == budgets


BEST_FOLDERS = [folder for folder in FOLDERS if folder.name.endswith("_best")]


@pytest.mark.skipif(not BEST_FOLDERS, reason="no committed --model best scores")
@pytest.mark.parametrize("folder", BEST_FOLDERS, ids=[folder.name for folder in BEST_FOLDERS])
def test_committed_best_models_are_those_of_the_scored_grid(folder):
    """``--model best`` scores other models of the same runs: same algorithms, seeds, settings and training."""
    grid = folder.with_name(folder.name.removesuffix("_best"))
    best, final = (json.loads((path / "metadata.json").read_text()) for path in (folder, grid))
    assert best["model"].startswith("each run's best_model.zip")
    assert final.get("model", "each run's final model") == "each run's final model"
    for key in ("env", "robot", "algos", "seeds", "n_timesteps", "hyperparams", "configs", "training_wall_time_s"):
        assert best.get(key) == final.get(key), key
    # The runs' final evaluations (written by training) are the grid's.
    pd.testing.assert_frame_equal(pd.read_csv(folder / "final.csv"), pd.read_csv(grid / "final.csv"))
    scores = pd.read_csv(folder / "success.csv")
    assert set(scores[["algo", "seed"]].itertuples(index=False, name=None)) == set(
        pd.read_csv(grid / "success.csv")[["algo", "seed"]].itertuples(index=False, name=None)
    )


def assert_shipped_v1_entry_is(algo: str, measured, unnamed: tuple[str, ...] = ()) -> None:
    """The shipped ``algo`` ``-v1`` entry is the ``measured`` configuration with 300,000 steps, the budget of every
    shipped ``-v1`` entry. ``unnamed``: keys the shipped entry names and the runs left to their defaults (checked by
    the caller)."""
    from sb3_adc.config.loader import load_hyperparams

    shipped = load_hyperparams(algo, V1)
    assert shipped.source.endswith(f"[{V1}]")
    shipped_saved = {key: value for key, value in shipped.saved.items() if key not in unnamed}
    assert all(key not in measured.saved for key in unnamed)
    assert shipped_saved.pop("n_timesteps") == 300_000
    assert shipped_saved == {key: value for key, value in measured.saved.items() if key != "n_timesteps"}
    assert shipped.env_kwargs == measured.env_kwargs


def assert_shipped_v1_entry_is_measured(grid_settings, algo: str, configs_name: str, unnamed: tuple[str, ...] = ()):
    """The shipped ``algo`` ``-v1`` entry equals what the committed grid of ``configs_name`` trained: the frozen
    starting entry with the file's overrides, the grid's 300,000 steps as its budget. ``unnamed``: as
    :func:`assert_shipped_v1_entry_is`."""
    from sb3_adc.config.loader import load_hyperparams

    configs = ROOT / "benchmarks" / "configs" / "procedural_generalisation" / configs_name
    settings = _procedural_settings(grid_settings, ["--configs", str(configs), "--validation"])
    run = settings.train_settings(settings.grid()[0])
    assert run.algo == algo
    # Their budget is the grid's (the file's n_timesteps), not their starting entry's.
    assert settings.n_timesteps == 300_000
    measured = load_hyperparams(algo, V1, run.conf_file, run.overrides)
    assert_shipped_v1_entry_is(algo, measured, unnamed)


#: The algorithms whose ``-v1`` entries a pre-registered sweep on the tuning seeds chose, with its configs file
#: (``benchmarks/configs/budget_sweep/``); the rule is ``budget_sweep.winner``.
SWEEP_CHOSEN = {"ddpg": "ddpg_actor_average_150k", "sac": "sac_sectors_150k"}


@pytest.mark.parametrize("algo", sorted(SWEEP_CHOSEN))
def test_the_shipped_v1_entry_is_what_its_pre_registered_sweep_chose(algo, monkeypatch):
    """The shipped ``-v1`` entry of an algorithm chosen by a sweep is the configuration the rule picks from the
    committed sweep (its configs file over the frozen starting entry), with the 300,000 steps every entry ships."""
    import importlib
    import sys

    from sb3_adc.config.loader import load_hyperparams

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    monkeypatch.delitem(sys.modules, "budget_sweep", raising=False)
    monkeypatch.delitem(sys.modules, "procedural_generalisation", raising=False)
    budget_sweep = importlib.import_module("budget_sweep")
    name = SWEEP_CHOSEN[algo]
    configs = budget_sweep.read_configs(str(ROOT / "benchmarks" / "configs" / "budget_sweep" / f"{name}.yml"))
    results = ROOT / "benchmarks" / "results" / "budget_sweep" / f"LidarObstacleCourse-v1_{algo}_{name}"
    metadata = json.loads((results / "metadata.json").read_text())
    # The committed sweep is this file's, on the tuning seeds, at the budget the rule names.
    assert (metadata["algo"], metadata["configs_file"]) == (algo, f"benchmarks/configs/budget_sweep/{name}.yml")
    assert json.loads(json.dumps(configs)) == metadata["configs"]
    assert (metadata["seeds"], metadata["n_timesteps"]) == ([0, 1, 2, 3, 4], 150_000)
    chosen = budget_sweep.winner(pd.read_csv(results / "sweep.csv"), configs)
    starting = str(budget_sweep.STARTING_ENTRIES / f"{algo}.yml")
    assert_shipped_v1_entry_is(algo, load_hyperparams(algo, V1, starting, configs[chosen]))


def test_the_shipped_td3_entry_of_v1_is_the_measured_configuration(grid_settings):
    """The shipped TD3 ``-v1`` entry trains what its committed evidence measured:
    ``n_step_td3_300k_sectors_average.yml`` over the frozen starting entry."""
    assert_shipped_v1_entry_is_measured(grid_settings, "td3", "n_step_td3_300k_sectors_average.yml")


def test_the_shipped_adc_entry_of_v1_is_the_measured_configuration(grid_settings):
    """The shipped ADC ``-v1`` entry trains what its committed evidence measured: the configuration of
    ``n_step_300k_sectors_average.yml`` over the frozen starting entry, the critic design its runs used included."""
    from sb3_adc.adc.policies import DEFAULT_CRITIC_DESIGN
    from sb3_adc.config.loader import load_hyperparams

    # The runs did not name a design: they were trained with the default, which the shipped entry names.
    assert load_hyperparams("adc", V1).saved["critic_design"] == DEFAULT_CRITIC_DESIGN
    assert_shipped_v1_entry_is_measured(grid_settings, "adc", "n_step_300k_sectors_average.yml", ("critic_design",))


@pytest.mark.parametrize(("robot", "configs"), [("kinematic", False), ("wheeled", False), ("wheeled", True)])
def test_recorded_entries_are_what_the_engine_trains_and_go_stale_when_an_entry_changes(
    tmp_path, monkeypatch, grid_settings, robot, configs
):
    """``entries`` of a grid's ``metadata.json`` are the hyperparameters the engine resolves for the grid's runs (what
    their ``config.yml`` holds); once the entry they came from changes, ``stale_entries`` names the algorithm."""
    import importlib
    import shutil

    import yaml

    from sb3_adc.config import loader

    metadata = {"env": V1, "robot": robot, "n_timesteps": "each entry's n_timesteps"}
    argv = ["--algos", "td3", "--robot", robot]
    if configs:
        path = tmp_path / "configs.yml"
        path.write_text("td3: {gamma: 0.96, n_timesteps: 1000}\n")
        argv = ["--configs", str(path), *argv]
        metadata |= {"configs": {"td3": {"gamma": 0.96}}, "n_timesteps": {"td3": 1000}}
    settings = _procedural_settings(grid_settings, argv)
    module = importlib.import_module("procedural_generalisation")  # the one grid_settings ran, its folders in tmp_path
    run = settings.train_settings(settings.grid()[0])
    engine = loader.load_hyperparams("td3", V1, run.conf_file, run.overrides, run.n_timesteps)
    recorded = json.loads(json.dumps(yaml.safe_load(yaml.safe_dump(engine.saved))))  # through metadata.json
    assert recorded == module.trained_entry("td3", V1, run.conf_file, run.overrides, settings.n_timesteps)
    assert module.stale_entries({**metadata, "entries": {"td3": recorded}}) == []
    assert recorded["env_kwargs"].get("robot", "kinematic") == robot
    assert recorded["n_timesteps"] == (1000 if configs else 300_000)
    # The entry the grid read changes afterwards (the frozen starting entry, or the shipped one): stale.
    changed = tmp_path / "entries"
    changed.mkdir()
    if configs:
        shutil.copy(module.STARTING_ENTRIES / "td3.yml", changed / "td3.yml")
        monkeypatch.setattr(module, "STARTING_ENTRIES", changed)
    else:
        shutil.copy(loader.packaged_hyperparams_file("td3"), changed / "td3.yml")
        packaged = loader.packaged_hyperparams_file
        monkeypatch.setattr(
            loader, "packaged_hyperparams_file", lambda name: str(changed / "td3.yml") if name == "td3" else packaged(name)
        )
    entries = loader.read_hyperparams_file(str(changed / "td3.yml"))
    entries[V1] = {**entries[V1], "batch_size": 512}
    (changed / "td3.yml").write_text(yaml.safe_dump(entries))
    assert module.stale_entries({**metadata, "entries": {"td3": recorded}}) == ["td3"]
    # Only the algorithms asked about are checked.
    assert module.stale_entries({**metadata, "entries": {"td3": recorded}}, ["sac"]) == []


def test_committed_grids_trained_the_entries_their_command_trains_today(monkeypatch):
    """A committed grid's numbers are what its command reproduces: no entry it recorded has changed since (else re-run
    the grid, or keep it under a name of its own as ``..._first_entries``)."""
    import importlib
    import sys

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    monkeypatch.delitem(sys.modules, "procedural_generalisation", raising=False)
    module = importlib.import_module("procedural_generalisation")
    recorded = {folder.name: json.loads((folder / "metadata.json").read_text()) for folder in FOLDERS}
    recorded = {name: metadata for name, metadata in recorded.items() if "entries" in metadata}
    if not recorded:
        pytest.skip("no committed grid records its entries")
    stale = {name: algos for name, metadata in recorded.items() if (algos := module.stale_entries(metadata))}
    assert not stale, f"entries changed since these grids ran: {stale}"
    sys.modules.pop("procedural_generalisation", None)
