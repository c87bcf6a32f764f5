"""
Benchmark grids: algorithms x environments x seeds, one training run each, in parallel processes (default) or
as Ray tasks on a Ray cluster, resumable, summarised in tidy CSVs.

Run ``(algo, env, seed)`` lives in ``{log_folder}/{algo}/{env_name}_seed{seed}/`` (the RL-Zoo run layout
with the seed as run name). Re-running a grid keeps finished runs (they are skipped), resumes interrupted
ones from their last checkpoint and starts the others. Results are written to ``{log_folder}``:
``evaluations.csv`` (the evaluation curves), ``episodes.csv`` (training episodes) and ``final.csv`` (final
evaluations); see :mod:`sb3_adc.experiment.results` for the columns.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import traceback
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from sb3_adc.experiment.layout import RunLayout, env_name
from sb3_adc.experiment.results import (
    EPISODE_COLUMNS,
    EVALUATION_COLUMNS,
    FINAL_COLUMNS,
    Row,
    episode_rows,
    evaluation_rows,
    final_row,
    write_table,
)
from sb3_adc.experiment.settings import TrainSettings

#: File names of the tables a benchmark writes in its log folder.
EVALUATIONS_CSV = "evaluations.csv"
EPISODES_CSV = "episodes.csv"
FINAL_CSV = "final.csv"


@dataclass(frozen=True)
class RunSpec:
    """
    One run of the grid.

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

    def grid(self) -> list[RunSpec]:
        """Every (algorithm, environment, seed) combination, in that order."""
        return [RunSpec(algo, env_id, seed) for algo in self.algos for env_id in self.env_ids for seed in self.seeds]

    def train_settings(self, spec: RunSpec) -> TrainSettings:
        """
        The training settings of one run.

        :param spec: The run
        """
        conf_file = None if self.conf_folder is None else os.path.join(self.conf_folder, f"{spec.algo}.yml")
        return TrainSettings(
            algo=spec.algo,
            env_id=spec.env_id,
            seed=spec.seed,
            conf_file=conf_file,
            overrides=dict(self.overrides),
            n_timesteps=self.n_timesteps,
            log_folder=self.log_folder,
            run_dir=spec.run_dir(self.log_folder),
            eval_freq=self.eval_freq,
            eval_episodes=self.eval_episodes,
            final_eval_episodes=self.final_eval_episodes,
            device=self.device,
            progress_bar=False,
        )


@dataclass
class RunOutcome:
    """
    What a run of the grid produced.

    :param spec: The run
    :param status: ``skipped`` (finished before), ``resumed``, ``trained`` or ``failed``
    :param evaluations: Its evaluation-curve rows
    :param episodes: Its training-episode rows
    :param final: Its final-evaluation row (``None`` if it failed)
    :param error: The traceback of a failed run
    """

    spec: RunSpec
    status: str
    evaluations: list[Row] = field(default_factory=list)
    episodes: list[Row] = field(default_factory=list)
    final: Row | None = None
    error: str = ""


def run_one(spec: RunSpec, settings: BenchmarkSettings) -> RunOutcome:
    """
    Train, resume or skip one run, and read back its results. Never raises: a failure is an outcome.

    :param spec: The run
    :param settings: The grid's settings
    """
    from sb3_adc.experiment.training import resume, train

    run_dir = spec.run_dir(settings.log_folder)
    layout = RunLayout(run_dir, spec.env_id)
    try:
        if layout.is_finished():
            status = "skipped"
        elif os.path.isfile(layout.args):
            resume(run_dir, progress_bar=False)
            status = "resumed"
        else:
            train(settings.train_settings(spec))
            status = "trained"
        return RunOutcome(
            spec,
            status,
            evaluations=evaluation_rows(layout, spec.algo, spec.seed),
            episodes=episode_rows(layout, spec.algo, spec.seed),
            final=final_row(layout, spec.algo, spec.seed),
        )
    except Exception:  # a failed run must not stop the grid
        return RunOutcome(spec, "failed", error=traceback.format_exc())


def _init_worker() -> None:
    import torch as th

    # One process per run: several torch threads per process would only compete for the same cores.
    th.set_num_threads(1)


def run_local(specs: list[RunSpec], settings: BenchmarkSettings, workers: int) -> Iterator[RunOutcome]:
    """
    Run the grid in a pool of ``workers`` processes; outcomes come as runs finish.

    :param specs: The runs
    :param settings: The grid's settings
    :param workers: Number of processes (1: in this process, one after the other)
    """
    if workers <= 1:
        for spec in specs:
            yield run_one(spec, settings)
        return
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(workers, mp_context=context, initializer=_init_worker) as pool:
        futures = [pool.submit(run_one, spec, settings) for spec in specs]
        for future in concurrent.futures.as_completed(futures):
            yield future.result()


def run_ray(specs: list[RunSpec], settings: BenchmarkSettings, address: str | None = None) -> Iterator[RunOutcome]:
    """
    Run the grid as Ray tasks, one run per task (one CPU each); outcomes come as runs finish.

    Uses the Ray instance this process is connected to, else connects to ``address`` (``ray.init(address)``;
    ``None`` starts a local instance). The tasks return their result rows, so the tables are complete even
    when the workers do not share the driver's file system; to resume interrupted runs, put ``log_folder`` on
    storage all nodes share.

    :param specs: The runs
    :param settings: The grid's settings
    :param address: Address of the Ray cluster (``ray.init(address=...)``)
    """
    import ray

    if not ray.is_initialized():
        ray.init(address=address)
    task = ray.remote(num_cpus=1)(_ray_run_one)
    pending = [task.remote(spec, settings) for spec in specs]
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        yield ray.get(done[0])


def _ray_run_one(spec: RunSpec, settings: BenchmarkSettings) -> RunOutcome:
    _init_worker()
    return run_one(spec, settings)


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
    Run a grid and write its tables (also when some runs fail: finished work is never lost).

    :param settings: The grid
    :param backend: ``local`` (a process pool) or ``ray``
    :param workers: Processes of the local backend (``None``: the number of CPUs)
    :param address: Ray cluster address (Ray backend)
    :param report: Called with (outcome, runs done, runs in total) as each run finishes
    """
    specs = settings.grid()
    if not specs:
        raise ValueError("the grid is empty: give at least one algorithm, environment and seed.")
    if backend == "local":
        outcomes_iterator: Iterable[RunOutcome] = run_local(specs, settings, workers or os.cpu_count() or 1)
    elif backend == "ray":
        outcomes_iterator = run_ray(specs, settings, address)
    else:
        raise ValueError(f"`backend` must be 'local' or 'ray', got {backend!r}.")
    outcomes: list[RunOutcome] = []
    try:
        for outcome in outcomes_iterator:
            outcomes.append(outcome)
            if report is not None:
                report(outcome, len(outcomes), len(specs))
    except KeyboardInterrupt:
        # Ctrl-C: the runs in progress saved a checkpoint; the tables keep the runs that finished.
        write_tables(outcomes, settings.log_folder)
        raise
    return BenchmarkResult(outcomes, write_tables(outcomes, settings.log_folder))


def write_tables(outcomes: list[RunOutcome], folder: str) -> dict[str, str]:
    """
    Write the evaluation, episode and final tables of the outcomes.

    :param outcomes: The runs' outcomes
    :param folder: Where to write them
    :return: Table name -> path
    """
    paths = {name: os.path.join(folder, name) for name in (EVALUATIONS_CSV, EPISODES_CSV, FINAL_CSV)}
    write_table([row for outcome in outcomes for row in outcome.evaluations], EVALUATION_COLUMNS, paths[EVALUATIONS_CSV])
    write_table([row for outcome in outcomes for row in outcome.episodes], EPISODE_COLUMNS, paths[EPISODES_CSV])
    write_table([outcome.final for outcome in outcomes if outcome.final is not None], FINAL_COLUMNS, paths[FINAL_CSV])
    return paths
