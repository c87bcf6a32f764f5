"""
Benchmark grids: algorithms x environments x seeds, one run each in ``{log_folder}/{algo}/{env_name}_seed{seed}/``,
in processes or Ray tasks (:mod:`~sb3_adc.experiment.backends`). A re-run skips finished runs, resumes interrupted ones
and refuses runs on disk made with other settings (:class:`RunSettingsMismatch`). The folder's tables
(:mod:`~sb3_adc.experiment.results`) hold all its finished runs, ``invocations.json`` each invocation
(:mod:`~sb3_adc.experiment.invocations`); one invocation at a time holds the folder's lock until they are written.
"""

from __future__ import annotations

import contextlib
import dataclasses
import glob
import os
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import yaml

from sb3_adc.config.loader import read_yaml_file
from sb3_adc.experiment.backends import RunOutcome, run_local, run_ray
from sb3_adc.experiment.invocations import InvocationJournal
from sb3_adc.experiment.layout import DamagedFileError, FolderLock, RunLayout, env_name
from sb3_adc.experiment.results import EPISODE_COLUMNS, EVALUATION_COLUMNS, FINAL_COLUMNS, write_table
from sb3_adc.experiment.settings import TrainSettings

#: File names of the tables a benchmark writes in its log folder.
EVALUATIONS_CSV, EPISODES_CSV, FINAL_CSV = "evaluations.csv", "episodes.csv", "final.csv"
INTERRUPTED = "Interrupted: finished runs are kept, running ones saved a checkpoint. Re-run the same command to continue."
#: What the holder of a benchmark log folder's lock is doing, for the error of a second invocation.
BENCHMARK_ACTIVITY = "running a benchmark in it (sb3-adc benchmark, an experiment or a benchmark script)"

#: Run settings not compared as given: those that do not change a run's results, and those compared through the
#: resolved hyperparameters they produce (``config.yml``).
_NOT_COMPARED = {"log_folder", "run_dir", "device", "verbose", "progress_bar", "keep_checkpoints"}
_NOT_COMPARED |= {"conf_file", "overrides", "env_kwargs", "n_timesteps"}
_RUN_FOLDER = re.compile(r"^.+_seed(\d+)$")
_GRID_ONLY = ("algos", "env_ids", "seeds", "conf_folder")


class RunSettingsMismatch(ValueError):
    """
    Runs on disk were made with other settings than the grid asks for (a user error: exit status 2).

    :param differences: Each mismatched run's folder and its differing keys, as ``key: on disk -> asked``
    """

    def __init__(self, differences: dict[str, list[str]]):
        lines = [f"  {run_dir}: {'; '.join(keys)}" for run_dir, keys in differences.items()]
        super().__init__(
            f"{len(differences)} run(s) on disk were made with other settings than this benchmark asks for "
            "(key: on disk -> asked):\n" + "\n".join(lines) + "\nUse another --log-folder, give the settings of "
            "those runs, or delete them to redo them."
        )
        self.differences = differences


@dataclass(frozen=True)
class RunSpec:
    """
    One run of the grid: its algorithm, environment id and seed.

    :param algo: The algorithm's name
    :param env_id: The environment id
    :param seed: The seed
    """

    algo: str
    env_id: str
    seed: int

    def run_dir(self, log_folder: str) -> str:
        """
        The run's folder: ``{log_folder}/{algo}/{env_name}_seed{seed}``.

        :param log_folder: The benchmark's log folder
        """
        return os.path.join(log_folder, self.algo, f"{env_name(self.env_id)}_seed{self.seed}")

    def __str__(self) -> str:
        return f"{self.algo} on {self.env_id}, seed {self.seed}"


@dataclass
class BenchmarkSettings:
    """
    A grid and the settings shared by its runs.

    :param algos: Algorithm names
    :param env_ids: Environment ids
    :param seeds: Seeds
    :param log_folder: Folder of the runs and of the result tables
    :param n_timesteps: Budget of every run (``None``: each entry's ``n_timesteps``)
    :param overrides: ``key: value`` applied to every run's hyperparameters
    :param conf_folder: Folder with ``{algo}.yml`` files to use instead of the shipped ones
    :param eval_freq: Timesteps between evaluations (``None``: 20 evaluations per run)
    :param eval_episodes: Episodes per periodic evaluation
    :param final_eval_episodes: Episodes of the final evaluation
    :param device: PyTorch device of the runs
    :param keep_checkpoints: How many of each run's latest checkpoints to keep (one per evaluation; a budget sweep keeps all)
    :param eval_env_kwargs: ``gym.make`` keywords of the evaluation environments only (a validation split)
    :param best_model_metric: What picks each run's ``best_model.zip`` (:class:`~sb3_adc.experiment.settings.TrainSettings`)
    """

    algos: list[str]
    env_ids: list[str]
    seeds: list[int]
    log_folder: str = "benchmark"
    n_timesteps: int | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    conf_folder: str | None = None
    eval_freq: int | None = None
    eval_episodes: int = 5
    final_eval_episodes: int = 10
    device: str = "cpu"
    keep_checkpoints: int = 2
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    best_model_metric: str = "return"

    def grid(self) -> list[RunSpec]:
        """Every (algorithm, environment, seed) combination, in that order."""
        return [RunSpec(algo, env_id, seed) for algo in self.algos for env_id in self.env_ids for seed in self.seeds]

    def train_settings(self, spec: RunSpec) -> TrainSettings:
        """
        The training settings of one run.

        :param spec: The run
        """
        conf_file = None if self.conf_folder is None else os.path.join(self.conf_folder, f"{spec.algo}.yml")
        # The other settings are named as TrainSettings' fields (asdict copies the dicts).
        shared = {key: value for key, value in dataclasses.asdict(self).items() if key not in _GRID_ONLY}
        run_dir = spec.run_dir(self.log_folder)
        return TrainSettings(**dataclasses.asdict(spec), **shared, conf_file=conf_file, run_dir=run_dir, progress_bar=False)


def check_runs_on_disk(settings: BenchmarkSettings) -> None:
    """
    Check every run's hyperparameters, and that the grid's runs on disk were made with its settings (so that skipping
    or resuming them gives the runs asked for): resolved hyperparameters (``config.yml``) and run settings (``args.yml``).

    :param settings: The grid
    :raises HyperparamsError: for invalid hyperparameters of a run
    :raises RunSettingsMismatch: naming each mismatched run and its differing keys
    """
    from sb3_adc.config import load_hyperparams

    differences: dict[str, list[str]] = {}
    for spec in settings.grid():
        asked = settings.train_settings(spec)
        config = load_hyperparams(spec.algo, spec.env_id, asked.conf_file, asked.overrides, asked.n_timesteps)
        layout = RunLayout(spec.run_dir(settings.log_folder), spec.env_id)
        if not os.path.isfile(layout.args) or not os.path.isfile(layout.config):
            continue
        saved = read_yaml_file(layout.config)
        keys = _differences(saved if isinstance(saved, dict) else {}, yaml.safe_load(yaml.safe_dump(config.saved)))
        keys += _differences(dataclasses.asdict(TrainSettings.load(layout.args)), dataclasses.asdict(asked), _NOT_COMPARED)
        if keys:
            differences[layout.run_dir] = keys
    if differences:
        raise RunSettingsMismatch(differences)


def _differences(saved: dict[str, Any], asked: dict[str, Any], ignored: set[str] | None = None) -> list[str]:
    missing = "(not set)"
    return [
        f"{key}: {saved.get(key, missing)!r} -> {asked.get(key, missing)!r}"
        for key in sorted((set(saved) | set(asked)) - (ignored or set()))
        if saved.get(key, missing) != asked.get(key, missing)
    ]


def runs_on_disk(log_folder: str) -> list[RunSpec]:
    """
    The benchmark runs in a log folder (``{algo}/{env_name}_seed{seed}/`` with their ``args.yml``), by folder.

    :param log_folder: The benchmark's log folder
    """
    specs = []
    for args_path in sorted(glob.glob(os.path.join(glob.escape(log_folder), "*", "*_seed*", "*", "args.yml"))):
        run_dir = os.path.dirname(os.path.dirname(args_path))
        if not _RUN_FOLDER.match(os.path.basename(run_dir)):
            continue
        try:
            saved = TrainSettings.load(args_path)
        except (ValueError, TypeError, yaml.YAMLError):
            continue
        spec = RunSpec(saved.algo, saved.env_id, saved.seed)
        if os.path.normpath(spec.run_dir(log_folder)) == os.path.normpath(run_dir):
            specs.append(spec)
    return specs


@dataclass
class BenchmarkResult:
    """
    The outcomes of a grid and the tables written.

    :param outcomes: One per run
    :param tables: Paths of ``evaluations.csv``, ``episodes.csv`` and ``final.csv``
    """

    outcomes: list[RunOutcome]
    tables: dict[str, str]

    @property
    def failures(self) -> list[RunOutcome]:
        return [outcome for outcome in self.outcomes if outcome.status == "failed"]


def run_benchmark(
    settings: BenchmarkSettings,
    backend: str = "local",
    workers: int | None = None,
    address: str | None = None,
    report: Callable[[RunOutcome, int, int], None] | None = None,
) -> BenchmarkResult:
    """
    :func:`run_benchmarks` of one grid.

    :param settings: The grid
    :param backend: ``local`` (a process pool) or ``ray``
    :param workers: Processes of the local backend (``None``: the number of CPUs)
    :param address: Ray cluster address (Ray backend)
    :param report: Called with (outcome, runs done, runs in total) as each run finishes
    """
    return run_benchmarks([settings], backend, workers, address, report)[0]


def run_benchmarks(
    grids: Sequence[BenchmarkSettings],
    backend: str = "local",
    workers: int | None = None,
    address: str | None = None,
    report: Callable[[RunOutcome, int, int], None] | None = None,
) -> list[BenchmarkResult]:
    """
    Run several grids in one pool of workers (busy until the last run) and write each grid's tables in its own log
    folder, also when runs fail or on Ctrl-C: finished work is never lost.

    :param grids: The grids (each its own ``log_folder``)
    :param backend: ``local`` (a process pool) or ``ray``
    :param workers: Processes of the local backend (``None``: the number of CPUs)
    :param address: Ray cluster address (Ray backend)
    :param report: Called with (outcome, runs done, runs in total) as each run finishes
    :return: One result per grid, in order
    :raises HyperparamsError: for invalid hyperparameters (before any run starts)
    :raises RunSettingsMismatch: if runs on disk were made with other settings (before any run starts)
    :raises RunLocked: if another invocation is working on one of the log folders (before anything is written)
    """
    folders = [os.path.normpath(settings.log_folder) for settings in grids]
    if len(set(folders)) < len(folders):
        raise ValueError(f"every grid needs its own `log_folder`, got {[settings.log_folder for settings in grids]}.")
    if backend not in ("local", "ray"):
        raise ValueError(f"`backend` must be 'local' or 'ray', got {backend!r}.")
    jobs = [(spec, settings) for settings in grids for spec in settings.grid()]
    for settings in grids:
        if not settings.grid():
            raise ValueError("the grid is empty: give at least one algorithm, environment and seed.")
        check_runs_on_disk(settings)  # before anything is written, the log folders included
    outcomes: dict[str, list[RunOutcome]] = {folder: [] for folder in folders}

    def write_all() -> list[dict[str, str]]:
        return [write_tables(outcomes[folder], grid.log_folder) for grid, folder in zip(grids, folders, strict=True)]

    with contextlib.ExitStack() as locks:
        # One invocation per log folder until its tables are written; the runs on disk are checked again under it.
        for folder in sorted(folders):
            locks.enter_context(FolderLock(folder, BENCHMARK_ACTIVITY))
        for settings in grids:
            check_runs_on_disk(settings)
        n_workers = workers or os.cpu_count() or 1
        sizes = [(folder, settings.algos, len(settings.grid())) for settings, folder in zip(grids, folders, strict=True)]
        journal = InvocationJournal(sizes, workers=n_workers if backend == "local" else "cluster", backend=backend)
        try:
            with journal:
                results = run_local(jobs, n_workers) if backend == "local" else run_ray(jobs, address)
                for done, outcome in enumerate(results, start=1):
                    outcomes[os.path.normpath(outcome.log_folder)].append(outcome)
                    journal.record(os.path.normpath(outcome.log_folder), outcome.status)
                    if report is not None:
                        report(outcome, done, len(jobs))
        except KeyboardInterrupt:  # the runs in progress saved a checkpoint; the tables keep the runs that finished
            write_all()
            raise
        return [BenchmarkResult(outcomes[folder], paths) for folder, paths in zip(folders, write_all(), strict=True)]


def write_tables(outcomes: list[RunOutcome], folder: str) -> dict[str, str]:
    """
    Write the evaluation, episode and final tables of the outcomes and of the folder's other finished runs (a smaller
    grid never drops the rows of an earlier one).

    :param outcomes: The runs' outcomes
    :param folder: Where to write them (the benchmark's log folder)
    :return: Table name -> path
    """
    done = {outcome.spec for outcome in outcomes}
    outcomes = list(outcomes)
    for spec in runs_on_disk(folder):
        if spec in done or not RunLayout(spec.run_dir(folder), spec.env_id).is_finished():
            continue
        try:
            outcomes.append(RunOutcome.read(spec, "skipped", folder))
        except (DamagedFileError, OSError, ValueError) as error:
            warnings.warn(f"the results of {spec} are left out of the tables: {error}", stacklevel=2)
    paths = {name: os.path.join(folder, name) for name in (EVALUATIONS_CSV, EPISODES_CSV, FINAL_CSV)}
    write_table([row for outcome in outcomes for row in outcome.evaluations], EVALUATION_COLUMNS, paths[EVALUATIONS_CSV])
    write_table([row for outcome in outcomes for row in outcome.episodes], EPISODE_COLUMNS, paths[EPISODES_CSV])
    write_table([outcome.final for outcome in outcomes if outcome.final is not None], FINAL_COLUMNS, paths[FINAL_CSV])
    return paths
