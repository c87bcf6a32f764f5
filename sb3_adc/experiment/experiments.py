"""
Experiments as data: one YAML file names a grid of configurations x environments x seeds, its budget, evaluation and
statistics; ``sb3-adc experiment FILE`` trains it on the benchmark engine
(:func:`~sb3_adc.experiment.benchmark.run_benchmarks`) and writes its tables and figures. Every committed result under
``benchmarks/results/`` that a page cites is one file of ``benchmarks/experiments/``. The file (read with the bounded
YAML reader: nothing in it is executed)::

    description: The shipped entries on the noisy Pendulum, fresh seeds
    envs: [sb3_adc/NoisyPendulum-v1]
    seeds: {start: 1000, stop: 1010}        # or a list
    n_timesteps: 20000                      # null: each entry's own budget
    evaluation: {episodes: 5, final_episodes: 20}   # and optionally every: <steps> (default: 20 evaluations a run)
    configs:                                # name -> algorithm, hyperparameter folder, overrides, figure label
      adc_shipped: {algo: adc}
      td3_tuned: {algo: td3, hyperparams: ../results/fair_tuning/hyperparams, label: TD3 (shipped)}
    reference: adc_shipped                  # P(reference > each other configuration)
    threshold: -300                         # optional: runs that stay above this return, and how soon
    runs: ../runs/noisy_pendulum_equal_tuning   # optional (default ../runs/<name>): shared runs train once
    results: ../results/noisy_pendulum_shipped  # optional (default ../results/<name>)
    figures: ../../docs/_static/benchmarks      # optional: where the figures go, as <name>_<figure>.png
    test_sets:                              # optional: held-out episodes scoring each finished run (test_sets.py)
      held-out layouts: {env_kwargs: {start_position_jitter: 0.0}, layout_seeds: {start: 1000000, stop: 1000100}}
      unseen course files: {env_kwargs: {start_position_jitter: 0.1}, courses: [unseen_posts], episodes: 10}
    diagnostics: {every: 2000, episodes: 5}  # optional, one env: each run logs the critic diagnostics
    tuning: {trials: 6, objective: return}  # optional, one env: an Optuna study per configuration (tuning_grid.py)

Paths are relative to the file's folder; ``hyperparams`` is a folder of ``{algo}.yml`` files, ``overrides`` are
``-params``. Each configuration is a grid in ``{runs}/{config}/``, its name in the merged tables' ``algo`` column.
Test sets (``model: best``: each run's ``best_model.zip``) are scored after the training; ``diagnostics`` go to
``diagnostics/`` and ``diagnostics_*.csv`` (:func:`~sb3_adc.experiment.summary.write_diagnostics`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from sb3_adc.config import ALGORITHMS, HyperparamsError, load_hyperparams
from sb3_adc.config.loader import read_yaml_file
from sb3_adc.experiment import test_sets as scoring
from sb3_adc.experiment.benchmark import BenchmarkSettings, RunOutcome, run_benchmarks
from sb3_adc.experiment.layout import FolderLock
from sb3_adc.experiment.test_sets import TestSet, is_int, read_test_sets
from sb3_adc.experiment.tuning_grid import Tuning, read_tuning

#: Keys of an experiment file and of one of its configurations.
KEYS: tuple[str, ...] = ("description", "envs", "seeds", "n_timesteps", "evaluation", "configs", "reference", "threshold")
KEYS += ("bootstrap_reps", "runs", "results", "figures", "test_sets", "diagnostics", "tuning")
CONFIG_KEYS = ("algo", "hyperparams", "overrides", "label", "reference", "search_space")
EVALUATION_KEYS = ("episodes", "final_episodes", "every")
DIAGNOSTICS_KEYS = ("every", "episodes")
#: Bounds on a file's grid, so that a typo cannot ask for a million runs.
MAX_CONFIGS, MAX_ENVS, MAX_SEEDS = 64, 16, 1000
#: Budget and grid of ``--tiny``: the file's whole pipeline on one seed and one environment, in seconds.
TINY_TIMESTEPS = 200


class ExperimentError(HyperparamsError):
    """An experiment file that cannot be run: the message names the file and the key (exit status 2 at the CLI)."""


@dataclass(frozen=True)
class Config:
    """
    One configuration of an experiment.

    :param algo: The algorithm
    :param hyperparams: Folder of ``{algo}.yml`` files (``None``: the shipped files)
    :param overrides: ``key: value`` overrides of its entries (``-params``)
    :param label: Its name in figures
    :param reference: The configuration it is compared with on the test sets (``None``: the experiment's reference)
    """

    algo: str
    hyperparams: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    label: str | None = None
    reference: str | None = None


@dataclass(frozen=True)
class Experiment:
    """
    An experiment file, read and checked (:func:`read_experiment`). Paths are absolute.

    :param name: The file's stem
    :param path: The file
    :param description: What it answers
    :param envs: Environment ids
    :param seeds: Seeds
    :param configs: Configuration name -> :class:`Config`
    :param n_timesteps: Budget of every run (``None``: each entry's)
    :param eval_episodes: Episodes of each periodic evaluation
    :param final_eval_episodes: Episodes of the final evaluation
    :param eval_freq: Timesteps between periodic evaluations (``None``: 20 evaluations per run)
    :param reference: The configuration whose probability of improvement on the others is reported
    :param threshold: A return that runs should reach and keep (optional)
    :param bootstrap_reps: Bootstrap replications of the CIs
    :param runs: Folder of the runs (one grid per configuration)
    :param results: Folder of the tables
    :param figures: Folder of the figures (``None``: none is kept)
    :param test_sets: Held-out test sets scoring each finished run (:mod:`~sb3_adc.experiment.test_sets`)
    :param diagnostics: ``{every: steps, episodes: n}``: each run logs the critic diagnostics every ``every`` steps
        (:class:`~sb3_adc.diagnostics.CriticDiagnosticsCallback`; ``None``: none)
    :param tuning: One Optuna study per configuration instead of the grid (:mod:`~sb3_adc.experiment.tuning_grid`)
    """

    name: str
    path: str
    description: str
    envs: list[str]
    seeds: list[int]
    configs: dict[str, Config]
    n_timesteps: int | None = None
    eval_episodes: int = 5
    final_eval_episodes: int = 20
    eval_freq: int | None = None
    reference: str | None = None
    threshold: float | None = None
    bootstrap_reps: int = 5000
    runs: str = ""
    results: str = ""
    figures: str | None = None
    test_sets: dict[str, TestSet] = field(default_factory=dict)
    diagnostics: dict[str, int] | None = None
    tuning: Tuning | None = None

    def grids(self, tiny: bool = False, runs: str | None = None) -> dict[str, BenchmarkSettings]:
        """
        One benchmark grid per configuration.

        :param tiny: The first environment and seed only, :data:`TINY_TIMESTEPS` steps, two evaluations of one episode
        :param runs: Folder of the runs instead of :attr:`runs`
        """
        return {
            name: BenchmarkSettings(
                algos=[config.algo],
                env_ids=self.envs[:1] if tiny else list(self.envs),
                seeds=self.seeds[:1] if tiny else list(self.seeds),
                log_folder=os.path.join(runs or self.runs, name),
                n_timesteps=TINY_TIMESTEPS if tiny else self.n_timesteps,
                overrides={**config.overrides, **self._diagnostics_callback(os.path.join(runs or self.runs, name), tiny)},
                conf_folder=config.hyperparams,
                eval_freq=TINY_TIMESTEPS // 2 if tiny else self.eval_freq,
                eval_episodes=1 if tiny else self.eval_episodes,
                final_eval_episodes=1 if tiny else self.final_eval_episodes,
            )
            for name, config in self.configs.items()
        }

    def _diagnostics_callback(self, folder: str, tiny: bool) -> dict[str, Any]:
        """The ``callback`` override logging each run's critic diagnostics to ``{folder}/diagnostics/seed{seed}``."""
        if self.diagnostics is None:
            return {}
        every = TINY_TIMESTEPS // 2 if tiny else self.diagnostics["every"]
        episodes = 1 if tiny else self.diagnostics["episodes"]
        kwargs = {"eval_env": self.envs[0], "eval_freq": every, "log_freq": every, "n_eval_episodes": episodes}
        kwargs["save_path"] = os.path.join(folder, "diagnostics", "seed{seed}")
        return {"callback": {"sb3_adc.diagnostics.CriticDiagnosticsCallback": kwargs}}

    def references(self) -> dict[str, str | None]:
        """Each configuration's reference on the test sets: its own, else the experiment's."""
        return {name: config.reference or self.reference for name, config in self.configs.items()}

    def resolved(self) -> dict[str, dict[str, dict[str, Any]]]:
        """
        Each configuration's hyperparameters on each environment, as its runs save them (``config.yml``).

        :raises HyperparamsError: for a configuration whose entry is missing or invalid
        """
        resolved: dict[str, dict[str, dict[str, Any]]] = {}
        for name, config in self.configs.items():
            conf_file = None if config.hyperparams is None else os.path.join(config.hyperparams, f"{config.algo}.yml")
            resolved[name] = {
                env: load_hyperparams(config.algo, env, conf_file, dict(config.overrides), self.n_timesteps).saved
                for env in self.envs
            }
        return resolved

    def record(self, root: str) -> dict[str, Any]:
        """
        The settings of the results as ``metadata.json`` records them (paths relative to ``root``), with every
        configuration's resolved entries (:meth:`resolved`, so that a test can see them change).

        :param root: The repository root
        """
        return {
            "experiment": os.path.relpath(self.path, root),
            "configs": {
                name: {
                    "algo": config.algo,
                    "overrides": dict(config.overrides),
                    "hyperparams": "shipped" if config.hyperparams is None else os.path.relpath(config.hyperparams, root),
                    **({"reference": config.reference} if config.reference else {}),
                }
                for name, config in self.configs.items()
            },
            "reference": self.reference,
            "envs": list(self.envs),
            "seeds": list(self.seeds),
            "n_timesteps": self.n_timesteps,
            "eval": f"{self.eval_episodes} deterministic episodes per evaluation, "
            f"{'20 per run' if self.eval_freq is None else f'every {self.eval_freq} steps'}; "
            f"final: {self.final_eval_episodes} deterministic episodes",
            "resolved": self.resolved(),
            **({"test_sets": {name: test.record() for name, test in self.test_sets.items()}} if self.test_sets else {}),
            **({"diagnostics": dict(self.diagnostics)} if self.diagnostics else {}),
        }


def _require(condition: bool, path: str, key: str, problem: str) -> None:
    if not condition:
        raise ExperimentError(path, key, problem)


def _check_keys(data: Any, accepted: tuple[str, ...], path: str, where: str) -> None:
    _require(isinstance(data, Mapping), path, where, f"must be a mapping of {', '.join(accepted)}")
    unknown = sorted(set(data) - set(accepted))
    _require(not unknown, path, where, f"has unknown keys {unknown}; accepted: {', '.join(accepted)}")


def _seeds(value: Any, path: str) -> list[int]:
    problem = f"must list 1 to {MAX_SEEDS} distinct seeds >= 0, or be {{start: int, stop: int}}"
    if isinstance(value, Mapping):
        _check_keys(value, ("start", "stop"), path, "seeds")
        start, stop = value.get("start", 0), value.get("stop", 0)
        _require(is_int(start, 0, 2**31) and is_int(stop, start + 1, start + MAX_SEEDS), path, "seeds", problem)
        value = list(range(start, stop))
    _require(isinstance(value, list) and all(is_int(seed, 0, 2**31) for seed in value), path, "seeds", problem)
    _require(0 < len(value) <= MAX_SEEDS and len(set(value)) == len(value), path, "seeds", problem)
    return list(value)


def _folder(value: Any, path: str, key: str) -> str | None:
    if value is None:
        return None
    _require(isinstance(value, str) and value != "", path, key, "must be a folder path (relative to the file's folder)")
    return os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), value))


def _config(name: Any, value: Any, path: str) -> Config:
    key = f"configs.{name}"
    _require(isinstance(name, str) and name.isidentifier(), path, key, "must be named with letters, digits and _")
    _check_keys(value, CONFIG_KEYS, path, key)
    algo, overrides, label = value.get("algo"), value.get("overrides") or {}, value.get("label")
    _require(algo in ALGORITHMS.names(), path, f"{key}.algo", f"must be one of {', '.join(ALGORITHMS.names())}")
    _require(isinstance(overrides, Mapping), path, f"{key}.overrides", "must be a mapping of hyperparameters")
    _require(label is None or isinstance(label, str), path, f"{key}.label", "must be a string")
    hyperparams = _folder(value.get("hyperparams"), path, f"{key}.hyperparams")
    if hyperparams is not None:
        conf_file = os.path.join(hyperparams, f"{algo}.yml")
        _require(os.path.isfile(conf_file), path, f"{key}.hyperparams", f"has no {algo}.yml ({conf_file})")
    return Config(str(algo), hyperparams, dict(overrides), label, value.get("reference"))


def read_experiment(path: str) -> Experiment:
    """
    Read and check an experiment file.

    :param path: The file
    :raises ExperimentError: naming the key of anything the file gets wrong
    :raises HyperparamsError: if the file is not bounded UTF-8 YAML
    """
    if not os.path.isfile(path):
        raise ExperimentError(path, None, "no such experiment file")
    data = read_yaml_file(path)
    _check_keys(data, KEYS, path, "the file")
    name = os.path.splitext(os.path.basename(path))[0]
    envs, configs, n_timesteps = data.get("envs"), data.get("configs"), data.get("n_timesteps")
    envs_ok = isinstance(envs, list) and 0 < len(envs) <= MAX_ENVS and all(isinstance(env, str) for env in envs)
    _require(envs_ok, path, "envs", f"must list 1 to {MAX_ENVS} env ids")
    problem = f"must map 1 to {MAX_CONFIGS} names to configurations"
    _require(isinstance(configs, Mapping) and 0 < len(configs) <= MAX_CONFIGS, path, "configs", problem)
    _require(n_timesteps is None or is_int(n_timesteps, 1, 10**9), path, "n_timesteps", "must be in 1-1e9 or null")
    evaluation = data.get("evaluation") or {}
    _check_keys(evaluation, EVALUATION_KEYS, path, "evaluation")
    episodes, final_episodes = evaluation.get("episodes", 5), evaluation.get("final_episodes", 20)
    for key, value in (("episodes", episodes), ("final_episodes", final_episodes)):
        _require(is_int(value, 1, 1000), path, f"evaluation.{key}", "must be an integer in 1-1000")
    every = evaluation.get("every")
    _require(every is None or is_int(every, 1, 10**9), path, "evaluation.every", "must be an integer in 1-1e9 (steps)")
    reference, threshold = data.get("reference"), data.get("threshold")
    _require(reference is None or reference in configs, path, "reference", f"must be one of the configs {list(configs)}")
    for key, value in configs.items():
        problem = f"must be one of the configs {list(configs)}"
        _require((value or {}).get("reference", reference) in (*configs, None), path, f"configs.{key}.reference", problem)
    _require(threshold is None or isinstance(threshold, int | float), path, "threshold", "must be a number")
    reps, description = data.get("bootstrap_reps", 5000), data.get("description", "")
    _require(is_int(reps, 100, 100_000), path, "bootstrap_reps", "must be an integer in 100-100000")
    _require(isinstance(description, str), path, "description", "must be a string")
    diagnostics = data.get("diagnostics")
    if diagnostics is not None:
        _check_keys(diagnostics, DIAGNOSTICS_KEYS, path, "diagnostics")
        _require(len(envs) == 1, path, "diagnostics", "needs exactly one env (its evaluation rollouts run on it)")
        diagnostics = {"every": diagnostics.get("every", 1000), "episodes": diagnostics.get("episodes", 5)}
        for key, high in (("every", 10**9), ("episodes", 1000)):
            _require(is_int(diagnostics[key], 1, high), path, f"diagnostics.{key}", "must be an integer >= 1")
    test_sets = read_test_sets(data.get("test_sets"), path)
    experiment = Experiment(
        name=name,
        path=os.path.abspath(path),
        description=description,
        envs=list(envs),
        seeds=_seeds(data.get("seeds"), path),
        configs={str(key): _config(key, value, path) for key, value in configs.items()},
        n_timesteps=n_timesteps,
        eval_episodes=episodes,
        final_eval_episodes=final_episodes,
        eval_freq=every,
        reference=reference,
        threshold=None if threshold is None else float(threshold),
        bootstrap_reps=reps,
        runs=str(_folder(data.get("runs", f"../runs/{name}"), path, "runs")),
        results=str(_folder(data.get("results", f"../results/{name}"), path, "results")),
        figures=_folder(data.get("figures"), path, "figures"),
        test_sets=test_sets,
        diagnostics=diagnostics,
    )
    experiment = dataclasses.replace(experiment, tuning=read_tuning(data, experiment))
    problem = "is tuning.n_evaluations in a tuning file"
    _require(every is None or experiment.tuning is None, path, "evaluation.every", problem)
    return experiment


def run_experiment(
    experiment: Experiment,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    report: Callable[[RunOutcome, int, int], None] | None = None,
    tiny: bool = False,
) -> list[RunOutcome]:
    """
    Train, resume or skip every run of the experiment in one pool of workers, then write its tables and figures.

    :param experiment: The experiment
    :param workers: Processes of the local backend (``None``: the number of CPUs)
    :param backend: ``local`` or ``ray``
    :param address: Ray cluster address
    :param report: Called with (outcome, runs done, runs in total) as each run finishes
    :param tiny: The file's whole pipeline on one seed and environment, :data:`TINY_TIMESTEPS` steps and 100
        bootstrap replications, in a temporary folder: a check that the file runs, not a result
    :return: The runs' outcomes (failed runs included: the tables hold the others)
    :raises RunLocked: if another invocation works on the results folder or on a grid (before anything is written)
    """
    if tiny:
        experiment = dataclasses.replace(experiment, bootstrap_reps=100)
    scratch_folder = tempfile.TemporaryDirectory(prefix=f"{experiment.name}_tiny_") if tiny else contextlib.nullcontext("")
    # One invocation writes the results folder at a time (a tiny run writes only in its own scratch folder).
    results_lock = contextlib.nullcontext() if tiny else FolderLock(experiment.results, "running an experiment in it")
    with results_lock, scratch_folder as scratch:
        runs = os.path.join(scratch, "runs") if scratch else None
        grids = experiment.grids(tiny=tiny, runs=runs)
        results = run_benchmarks(list(grids.values()), backend, workers, address, report)
        outcomes = [outcome for result in results for outcome in result.outcomes]
        from sb3_adc.experiment.summary import merge_tables, write_diagnostics, write_report

        output = os.path.join(scratch, "results") if scratch else experiment.results
        finished = {
            (name, run.spec.env_id, run.spec.seed): run.spec.run_dir(run.log_folder)
            for name, result in zip(grids, results, strict=True)
            for run in result.outcomes
            if run.final is not None
        }
        if finished:
            merge_tables({name: result.tables for name, result in zip(grids, results, strict=True)}, output)
            if experiment.test_sets:  # each finished run scored (tiny: on two layouts or one episode per test set)
                test_sets = {name: test.tiny() if tiny else test for name, test in experiment.test_sets.items()}
                scoring.score(finished, test_sets, output, workers or 1)
            if experiment.diagnostics:
                write_diagnostics(experiment, runs or experiment.runs, output, None if tiny else experiment.figures)
            folders = [grid.log_folder for grid in grids.values()]
            write_report(experiment, output, figures=None if tiny else experiment.figures, grids=folders)
    return outcomes


def repository_root(experiment: Experiment) -> str:
    """
    The folder recorded paths are relative to: the repository of ``benchmarks/experiments/x.yml``, else the file's.

    :param experiment: The experiment
    """
    folder = os.path.dirname(experiment.path)
    if os.path.basename(folder) == "experiments" and os.path.basename(os.path.dirname(folder)) == "benchmarks":
        return os.path.dirname(os.path.dirname(folder))
    return folder
