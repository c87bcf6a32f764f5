"""
Hyperparameter tuning with Optuna (``sb3-adc train -optimize``), on the same engine as every other run.

The RL Zoo's ``hyperparameters_optimization``: a trial draws hyperparameters from the algorithm's search space
(:mod:`~sb3_adc.experiment.samplers`), periodic evaluations are reported to the pruner (the Zoo's
``TrialEvalCallback``), and its value is the final evaluation's mean return (``objective="return"``) or success
rate (``"success"``: the share of episodes ending with ``info["is_success"]``). Differences, each for a reason:

- The first trial is the algorithm's shipped entry: a tuned entry is at least as good on the tuning seeds.
- A trial trains several seeds (:func:`~sb3_adc.experiment.training.train`), so one lucky seed does not win, and
  can evaluate on other environment keywords (``eval_env_kwargs``: a validation split of layouts, say).
- ``search_space`` (``--search-space FILE``) gives choices per key, added to or replacing the algorithm's space.
- ``--n-jobs`` runs worker processes (threads share one interpreter lock) on one study, kept in a journal file by
  default. An interrupted trial (worker killed, Ctrl-C) is re-queued with its hyperparameters (Optuna's
  ``RetryHeartbeatStaleTrialCallback``) and keeps its runs: finished seeds are not trained again, an unfinished one
  resumes from its latest checkpoint. The budget is exactly ``n_trials`` finished trials whatever the number of
  workers: equal budgets make a comparison of tuned algorithms fair.

Files, under ``{log_folder}/tuning/{study_name}/``: ``study.log`` (the Optuna journal), ``trial_N/hyperparams.yml``
and ``trial_N/seed_S/`` (run folders; a continuation uses its trial's folder), ``trials.csv`` and
``best_hyperparams.yml`` (usable with ``-conf``), and ``.lock``: a study kept in a journal file is tuned by one
command at a time, which holds the study folder's lock (:class:`~sb3_adc.experiment.layout.FolderLock`) for its life
(its ``--n-jobs`` workers work under it), and a second command on the same folder fails at once with
:class:`~sb3_adc.experiment.layout.RunLocked`. A study in a database (``--storage`` URL) is shared on purpose by
commands on several machines or in one folder: no lock then. Two log folders can share one journal file too (each its
own study folder).
"""

from __future__ import annotations

import contextlib
import csv
import functools
import itertools
import math
import multiprocessing
import os
import re
import shutil
import socket
import stat
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from multiprocessing.sharedctypes import Synchronized
from types import SimpleNamespace
from typing import Any, cast

import gymnasium as gym
import numpy as np
import optuna
import torch as th
import yaml
from optuna.exceptions import ExperimentalWarning
from optuna.storages import RetryHeartbeatStaleTrialCallback
from optuna.storages.journal import JournalFileBackend, JournalFileSymlinkLock
from optuna.trial import FrozenTrial, TrialState
from rl_zoo3.callbacks import TrialEvalCallback as ZooTrialEvalCallback
from rl_zoo3.exp_manager import ExperimentManager
from stable_baselines3.common.callbacks import EvalCallback

from sb3_adc.common.atomic import write_atomically
from sb3_adc.config import HyperparamsError, load_hyperparams
from sb3_adc.config.loader import (
    apply_overrides,
    find_hyperparams_file,
    packaged_hyperparams_file,
    read_hyperparams_file,
    read_yaml_file,
    select_entry,
)
from sb3_adc.experiment.callbacks import TimestepSchedule
from sb3_adc.experiment.divergence import TrainingDiverged
from sb3_adc.experiment.envs import make_run_envs, wrap_vec_env
from sb3_adc.experiment.evaluation import FinalEvaluation, success_rate, success_unreported
from sb3_adc.experiment.layout import FolderLock, RunLayout, env_name
from sb3_adc.experiment.manager import RunInterrupted
from sb3_adc.experiment.samplers import SAMPLERS, Space, sample
from sb3_adc.experiment.settings import EVAL_SEED_OFFSET, TrainSettings, check_env_kwargs
from sb3_adc.experiment.training import resume, train

#: ``--sampler`` choices.
SAMPLER_NAMES = ("tpe", "random")
#: ``--pruner`` choices.
PRUNER_NAMES = ("median", "halving", "none")
#: ``--objective`` choices: what a trial's value is the mean of (the final evaluation's return or success rate).
OBJECTIVE_NAMES = ("return", "success")
#: Bounds of a search space (``--search-space``): keys, and choices per key.
MAX_SEARCH_KEYS = 32
MAX_CHOICES = 32
#: Workers (``--n-jobs``) per CPU at most: a worker trains on one thread and holds its own process (a few hundred
#: MB); more workers than that only share the CPUs.
MAX_JOBS_PER_CPU = 2
#: User attributes: the shipped entry's trial, the worker running a trial, its folder (relative to the study's),
#: the trial a continuation continues, and a trial stopped by Ctrl-C or a dead worker.
_SHIPPED, _WORKER, _TRIAL_DIR, _CONTINUES, _INTERRUPTED = "shipped", "worker", "trial_dir", "continues", "interrupted"
_refused = functools.partial(HyperparamsError, "command line")
#: Database URL schemes (``dialect`` or ``dialect+driver``) Optuna's ``RDBStorage`` opens.
DATABASE_DIALECTS = ("sqlite", "mysql", "postgresql")
# The password of a database URL (`scheme://user:password@host/...`).
_PASSWORD = re.compile(r"(?<=://)([^/@:]*):([^/@]*)@")


@dataclass
class TuneSettings:
    """
    What to tune and how.

    :param algo: The algorithm's name (one of :data:`~sb3_adc.experiment.samplers.SAMPLERS`)
    :param env_id: The environment id
    :param n_trials: Finished trials (complete or pruned) the study holds at the end, the shipped entry included
    :param n_timesteps: Training budget of each run (``None``: the entry's)
    :param seeds: Seeds each trial trains on (tune on seeds that the final comparison does not use)
    :param sampler: ``tpe`` (Optuna's default) or ``random``
    :param pruner: ``median``, ``halving`` (successive halving) or ``none``
    :param n_startup_trials: Trials sampled at random before TPE takes over and before the median pruner prunes
    :param n_evaluations: Evaluations per run reported to the pruner
    :param eval_episodes: Deterministic episodes of each of those evaluations
    :param final_eval_episodes: Deterministic episodes of each run's final evaluation (the trial's value)
    :param objective: ``return`` (mean return, the RL Zoo's) or ``success`` (success rate) of the evaluations
    :param n_jobs: Worker processes
    :param storage: Optuna storage: a database URL (``sqlite:///study.db``, needs SQLAlchemy) or a journal file
        (``*.log``); ``None``: ``study.log`` in the study folder
    :param study_name: The study's name (``None``: ``{algo}-{env}``)
    :param sampler_seed: Seed of the sampler (worker ``k`` uses ``sampler_seed + k``)
    :param conf_file: Hyperparameter file whose entry is the starting point (``None``: the shipped ``{algo}.yml``)
    :param overrides: Values fixed in every trial (``-params``), outside the search
    :param env_kwargs: Keyword arguments of ``gym.make``
    :param eval_env_kwargs: Keyword arguments of ``gym.make`` for the evaluations only (periodic and final),
        replacing those keys of ``env_kwargs`` (held-out layouts, say)
    :param search_space: Choices per key, drawn in every trial (see :class:`~sb3_adc.experiment.samplers.Space`)
    :param log_folder: Root of the log layout
    :param device: PyTorch device
    :param verbose: SB3 verbosity of the runs
    """

    algo: str
    env_id: str
    n_trials: int = 10
    n_timesteps: int | None = None
    seeds: tuple[int, ...] = (0,)
    sampler: str = "tpe"
    pruner: str = "median"
    n_startup_trials: int = 5
    n_evaluations: int = 5
    eval_episodes: int = 5
    final_eval_episodes: int = 10
    objective: str = "return"
    n_jobs: int = 1
    storage: str | None = None
    study_name: str | None = None
    sampler_seed: int = 0
    conf_file: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    search_space: dict[str, list[Any]] = field(default_factory=dict)
    log_folder: str = "logs"
    device: str = "auto"
    verbose: int = 0

    def __post_init__(self) -> None:
        if self.algo not in SAMPLERS:
            raise _refused("--algo", f"no search space for {self.algo!r}; tunable: {', '.join(SAMPLERS)}")
        for option, name, accepted in (
            ("--sampler", self.sampler, SAMPLER_NAMES),
            ("--pruner", self.pruner, PRUNER_NAMES),
            ("--objective", self.objective, OBJECTIVE_NAMES),
        ):
            if name not in accepted:
                raise _refused(option, f"{name!r}; accepted: {', '.join(accepted)}")
        self._check_search_space()
        for option, value, minimum in (
            ("--n-trials", self.n_trials, 1),
            ("--n-jobs", self.n_jobs, 1),
            ("--n-startup-trials", self.n_startup_trials, 0),
            ("--n-evaluations", self.n_evaluations, 1),
            ("--eval-episodes", self.eval_episodes, 1),
            ("--final-eval-episodes", self.final_eval_episodes, 1),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
                raise _refused(option, f"must be an integer >= {minimum}, got {value!r}")
        max_jobs = MAX_JOBS_PER_CPU * (os.cpu_count() or 1)
        if self.n_jobs > max_jobs:
            per_cpu = f"{MAX_JOBS_PER_CPU} per CPU of this machine"
            raise _refused("--n-jobs", f"must be an integer in [1, {max_jobs}] ({per_cpu}), got {self.n_jobs}")
        if self.n_timesteps is not None and self.n_timesteps < 1:
            raise _refused("--n-timesteps", f"must be >= 1, got {self.n_timesteps}")
        if not self.seeds or any(seed < 0 for seed in self.seeds) or len(set(self.seeds)) != len(self.seeds):
            raise _refused("--tuning-seeds", f"distinct seeds >= 0 are needed, got {list(self.seeds)}")
        self.seeds = tuple(int(seed) for seed in self.seeds)

    def _check_search_space(self) -> None:
        """The shape of :attr:`search_space`; its values are checked by :func:`check_search_space`."""
        space = self.search_space
        if not isinstance(space, dict) or not all(isinstance(key, str) for key in space):
            raise _refused("--search-space", f"must map hyperparameter names to lists of choices, got {space!r}")
        if len(space) > MAX_SEARCH_KEYS:
            raise _refused("--search-space", f"at most {MAX_SEARCH_KEYS} keys, got {len(space)}")
        for key, choices in space.items():
            option = f"--search-space {key}"
            if not isinstance(choices, list) or not 1 <= len(choices) <= MAX_CHOICES:
                raise _refused(option, f"must be a list of 1 to {MAX_CHOICES} choices, got {choices!r}")
            if key in self.overrides:
                raise _refused(option, "is fixed by -params: a key is either fixed or searched")
            if key in ("n_timesteps", "policy"):
                raise _refused(option, "is not searched: every trial has the same budget and policy")

    def evaluation_env_kwargs(self, entry_env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
        """
        The ``gym.make`` keywords of the evaluations: the entry's, then :attr:`env_kwargs`, then :attr:`eval_env_kwargs`.

        :param entry_env_kwargs: The ``env_kwargs`` of the trial's entry
        """
        return {**entry_env_kwargs, **self.env_kwargs, **self.eval_env_kwargs}

    @property
    def name(self) -> str:
        """The study's name."""
        return self.study_name or f"{self.algo}-{env_name(self.env_id)}"

    @property
    def study_dir(self) -> str:
        """The study's folder."""
        return os.path.join(self.log_folder, "tuning", self.name)

    def storage_url(self) -> str:
        """The storage, as given or the default journal file."""
        return self.storage or os.path.join(self.study_dir, "study.log")


@dataclass
class TuneResult:
    """
    The outcome of a study.

    :param study_dir: The study's folder
    :param best_value: The best trial's value (mean final return or success rate over the seeds)
    :param best_params: Its sampled hyperparameters (empty for the shipped entry)
    :param best_hyperparams_file: The hyperparameter file of the best trial (``-conf``)
    :param n_finished: Finished trials (complete or pruned)
    """

    study_dir: str
    best_value: float
    best_params: dict[str, Any]
    best_hyperparams_file: str
    n_finished: int


def tune(settings: TuneSettings) -> TuneResult:
    """
    Run (or continue) a study until it holds ``settings.n_trials`` finished trials.

    :param settings: What to tune
    :raises HyperparamsError: for invalid settings or hyperparameters, before any trial runs
    :raises RunLocked: if another command is tuning the study in its folder (a journal storage), before anything is
        written
    """
    base = _base_entry(settings)
    # Resolve the starting entry once: invalid hyperparameters stop here, before a folder is made.
    config = load_hyperparams(settings.algo, settings.env_id, settings.conf_file, settings.overrides, settings.n_timesteps)
    check_search_space(settings)
    evaluation_kwargs = settings.evaluation_env_kwargs(config.env_kwargs)
    if settings.eval_env_kwargs:
        check_env_kwargs(settings.env_id, evaluation_kwargs, "eval_env_kwargs")
    if settings.objective == "success":
        check_success_reported(settings, config.wrap_env(gym.make(settings.env_id, **evaluation_kwargs)))
    check_storage(settings.storage_url())
    with study_lock(settings):
        return _tune_locked(settings, base)


#: What the holder of a study folder's lock is doing, for the error of a second command.
TUNING_ACTIVITY = "tuning its study (one command per study kept in a journal file: use --n-jobs for more workers)"


def study_lock(settings: TuneSettings) -> contextlib.AbstractContextManager[Any]:
    """
    The lock :func:`tune` holds for its life: the study folder's :class:`~sb3_adc.experiment.layout.FolderLock`,
    unless the study is kept in a database (``--storage`` URL), which several commands share on purpose.

    :param settings: The study's settings
    """
    if "://" in settings.storage_url():
        return contextlib.nullcontext()
    return FolderLock(settings.study_dir, TUNING_ACTIVITY)


def _tune_locked(settings: TuneSettings, base: dict[str, Any]) -> TuneResult:
    """:func:`tune` from the journal's repair on, under :func:`study_lock`."""
    if "://" not in settings.storage_url():
        repair_journal(settings.storage_url())
    study = _open_study(settings, worker=0)  # a database it cannot open stops here, before the study's folder is made
    os.makedirs(settings.study_dir, exist_ok=True)
    _fail_dead_trials(study)
    _continue_interrupted(study)
    if not any(trial.user_attrs.get(_SHIPPED) and trial.state != TrialState.FAIL for trial in study.trials):
        study.enqueue_trial({}, user_attrs={_SHIPPED: True})
    remaining = settings.n_trials - len(_finished(study)) - len(study.get_trials(False, (TrialState.RUNNING,)))
    start = time.perf_counter()
    print(
        f"Tuning {settings.algo} on {settings.env_id}: study {settings.name} in {settings.study_dir}, "
        f"{len(_finished(study))} of {settings.n_trials} trials finished, seeds {list(settings.seeds)}, "
        f"{settings.n_jobs} worker(s)"
    )
    if remaining > 0:
        context = multiprocessing.get_context("spawn")
        # The trials still to run, taken one at a time by whichever worker is free. Optuna's MaxTrialsCallback (the
        # Zoo's budget) counts the study's trials after each one ends, and two workers ending at once can both
        # start one more: it overshoots by up to n_jobs - 1 trials. A shared count, taken under a lock, is exact.
        tickets = context.Value("i", remaining)
        n_workers = min(settings.n_jobs, remaining)
        if n_workers == 1:
            _work(settings, base, 0, tickets)
        else:
            workers = [
                context.Process(target=_work, args=(settings, base, k, tickets), name=f"tuning-worker-{k}")
                for k in range(n_workers)
            ]
            for worker in workers:
                worker.start()
            for worker in workers:
                worker.join()
            failed = [worker.name for worker in workers if worker.exitcode != 0]
            if failed:
                raise RuntimeError(f"{', '.join(failed)} stopped with an error; run the same command again to continue")
    result = _report(settings, _open_study(settings, worker=0))
    print(f"Tuning took {time.perf_counter() - start:.0f} s")
    return result


def _work(settings: TuneSettings, base: dict[str, Any], worker: int, tickets: Synchronized[int]) -> None:
    """One worker: run trials of the study while ``tickets`` (shared by the workers) has trials left to run."""
    th.set_num_threads(1)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = _open_study(settings, worker)
    while True:
        with tickets.get_lock():
            if tickets.value <= 0:
                return
            tickets.value -= 1
        study.optimize(lambda trial: _objective(trial, settings, base), n_trials=1, catch=())


def _objective(trial: optuna.Trial, settings: TuneSettings, base: dict[str, Any]) -> float:
    trial.set_user_attr(_WORKER, f"{socket.gethostname()}:{os.getpid()}")
    trial.set_user_attr(_INTERRUPTED, False)  # a continuation inherits the attributes of the trial it continues
    params = {}
    if not trial.user_attrs.get(_SHIPPED):
        params = sample(settings.algo, Space(trial, {**base, **settings.overrides}, settings.overrides, settings.search_space))
    entry = trial_entry(base, params, settings.overrides, settings.n_timesteps)
    earlier, folder = _continued_trial(trial, settings, entry)
    trial_dir = os.path.join(settings.study_dir, folder)
    os.makedirs(trial_dir, exist_ok=True)
    trial.set_user_attr(_TRIAL_DIR, folder)
    hyperparams_file = os.path.join(trial_dir, "hyperparams.yml")
    if earlier is None:
        _write_entry(hyperparams_file, settings.env_id, entry, f"trial {trial.number} of study {settings.name}")
    trial.set_user_attr("hyperparams", hyperparams_file)
    values = []
    try:
        for index, seed in enumerate(settings.seeds):
            final = _run_seed(trial, settings, hyperparams_file, trial_dir, index, seed, earlier)
            trial.set_user_attr(f"return_seed_{seed}", final.mean_return)
            if settings.objective == "success":
                trial.set_user_attr(f"success_seed_{seed}", final.success_rate)
            values.append(objective_value(settings, final.mean_return, final.success_rate))
    except RunInterrupted:
        trial.set_user_attr(_INTERRUPTED, True)  # the next invocation continues it (_continue_interrupted)
        raise
    value = float(np.mean(values))
    if not math.isfinite(value):
        raise optuna.TrialPruned(f"non-finite return {value}")
    return value


def _run_seed(
    trial: optuna.Trial,
    settings: TuneSettings,
    hyperparams_file: str,
    trial_dir: str,
    index: int,
    seed: int,
    earlier: Mapping[int, float] | None,
) -> FinalEvaluation:
    """Train (or, in a continued trial, resume or reuse) the run of one seed; its final evaluation."""
    run_dir = os.path.join(trial_dir, f"seed_{seed}")
    layout = RunLayout(run_dir, settings.env_id)
    first = index * settings.n_evaluations
    if earlier is not None and layout.is_finished():
        _carry_reports(trial, earlier, first, first + settings.n_evaluations)
        return resume(run_dir).final_evaluation
    callback = TrialEvalCallback(trial, settings, hyperparams_file, seed, step_offset=first, earlier=earlier)
    try:
        if earlier is not None and os.path.isdir(layout.params_dir):
            result = resume(run_dir, callbacks=[callback])
        else:
            run_settings = TrainSettings(
                algo=settings.algo,
                env_id=settings.env_id,
                seed=seed,
                conf_file=hyperparams_file,
                env_kwargs=dict(settings.env_kwargs),
                eval_env_kwargs=dict(settings.eval_env_kwargs),
                n_timesteps=settings.n_timesteps,
                log_folder=settings.log_folder,
                run_dir=run_dir,
                eval_freq=-1,
                save_freq=callback.interval,  # a checkpoint at every evaluation: a continuation resumes from there
                keep_checkpoints=1,
                final_eval_episodes=settings.final_eval_episodes,
                device=settings.device,
                verbose=settings.verbose,
                progress_bar=False,
            )
            result = train(run_settings, callbacks=[callback])
    except TrainingDiverged as error:
        # Sampled values that make training diverge (NaN or inf): a bad trial, not an error of the study.
        raise optuna.TrialPruned(f"seed {seed}: {error}") from None
    if callback.is_pruned:
        raise optuna.TrialPruned(f"pruned at evaluation {callback.n_reports} of seed {seed}")
    # A finished run is never trained further: its checkpoints (a replay buffer each) are only disk space.
    for checkpoint in layout.checkpoints():
        checkpoint.remove()
    return result.final_evaluation


def _continued_trial(
    trial: optuna.Trial, settings: TuneSettings, entry: Mapping[str, Any]
) -> tuple[dict[int, float] | None, str]:
    """
    For a trial that continues an interrupted one with the same entry: that trial's reported evaluations and its
    folder; otherwise ``None`` and the trial's own folder (a changed starting entry or ``-params`` start afresh).
    """
    own = f"trial_{trial.number}"
    trials = trial.study.get_trials(deepcopy=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExperimentalWarning)
        history = RetryHeartbeatStaleTrialCallback.retry_history(trials[trial.number])
    if not history:
        return None, own
    previous = trials[history[-1]]
    trial.set_user_attr(_CONTINUES, previous.number)
    folder = str(previous.user_attrs.get(_TRIAL_DIR, f"trial_{previous.number}"))
    path = os.path.join(settings.study_dir, folder, "hyperparams.yml")
    written = read_yaml_file(path).get(settings.env_id) if os.path.isfile(path) else None
    if written != yaml.safe_load(yaml.safe_dump(dict(entry))):
        print(f"Trial {trial.number}: the entry of trial {previous.number} changed since it ran; its runs are not reused")
        return None, own
    print(f"Trial {trial.number} continues trial {previous.number} in {folder}")
    return dict(previous.intermediate_values), folder


def _carry_reports(trial: optuna.Trial, earlier: Mapping[int, float], first: int, stop: int) -> None:
    """Report again to ``trial`` the values an interrupted trial reported at steps ``first`` to ``stop - 1``."""
    for step in range(first, stop):
        if step in earlier:
            trial.report(earlier[step], step)


def objective_value(settings: TuneSettings, mean_return: float, success_rate: float | None) -> float:
    """
    What an evaluation gives the study: its mean return, or its success rate (``objective="success"``).

    :raises HyperparamsError: for ``objective="success"`` where the environment reports no ``info["is_success"]``
    """
    if settings.objective == "return":
        return mean_return
    if success_rate is None:
        raise _refused(
            "--objective",
            f"'success' needs episodes that end with info['is_success'], which {settings.env_id} does not report; "
            f"accepted: {', '.join(OBJECTIVE_NAMES)}",
        )
    return success_rate


def check_success_reported(settings: TuneSettings, env: gym.Env) -> None:
    """
    ``objective="success"`` needs episodes that end with ``info["is_success"]``
    (:func:`~sb3_adc.experiment.evaluation.success_unreported`), checked before anything is written.

    :param env: The evaluation environment, with the entry's wrappers (closed here)
    :raises HyperparamsError: naming ``--objective`` if the episode ends without ``is_success`` or does not end
    """
    problem = success_unreported(env)
    if problem is not None:
        raise _refused(
            "--objective",
            f"'success' is the share of episodes ending with info['is_success'], but on {settings.env_id} {problem}; "
            f"accepted: {', '.join(OBJECTIVE_NAMES)}",
        )


def check_search_space(settings: TuneSettings) -> None:
    """
    Every choice of ``settings.search_space`` resolved with the starting entry, as ``-params`` would be, so that a
    choice the loader rejects stops the study before a folder is made.

    :raises HyperparamsError: naming the key and the choice
    """
    for key, choices in settings.search_space.items():
        for choice in choices:
            overrides = {**settings.overrides, key: choice}
            try:
                load_hyperparams(settings.algo, settings.env_id, settings.conf_file, overrides, settings.n_timesteps)
            except HyperparamsError as error:
                raise _refused(f"--search-space {key}", f"choice {choice!r}: {error}") from None


def trial_entry(
    base: Mapping[str, Any], params: Mapping[str, Any], overrides: Mapping[str, Any], n_timesteps: int | None = None
) -> dict[str, Any]:
    """
    The hyperparameter entry of a trial: the starting entry, the sampled values, then the fixed overrides, merged
    as :func:`~sb3_adc.config.loader.apply_overrides` merges ``-params`` (a drawn noise type other than
    ``epsilon-normal`` drops the starting entry's epsilon keys).

    :param base: The starting entry
    :param params: The sampled values
    :param overrides: Values fixed in every trial (``-params``)
    :param n_timesteps: The study's training budget (``None``: the entry's), written into the entry so that the
        trial's file, and the best one, train with ``-conf`` for as long as the trial did
    """
    entry = apply_overrides(base, {**params, **overrides})
    if n_timesteps is not None:
        entry["n_timesteps"] = n_timesteps
    return entry


class TrialEvalCallback(ZooTrialEvalCallback):
    """
    The RL Zoo's ``TrialEvalCallback``, evaluating a run ``n_evaluations`` times on the timestep count and reporting
    the study's objective, with the evaluation environment built from the trial's entry and ``eval_env_kwargs``,
    and the report steps of several seeds laid end to end.

    :param trial: The Optuna trial
    :param settings: The study's settings
    :param hyperparams_file: The trial's hyperparameter file
    :param seed: The run's seed
    :param step_offset: Report step of this run's first evaluation
    :param earlier: The evaluations an interrupted trial reported (by step), carried over for the part of a
        resumed run that its checkpoint covers
    """

    def __init__(
        self,
        trial: optuna.Trial,
        settings: TuneSettings,
        hyperparams_file: str,
        seed: int,
        step_offset: int,
        earlier: Mapping[int, float] | None = None,
    ):
        config = load_hyperparams(settings.algo, settings.env_id, hyperparams_file, n_timesteps=settings.n_timesteps)
        config.env_kwargs = settings.evaluation_env_kwargs(config.env_kwargs)
        eval_env = wrap_vec_env(config, make_run_envs(config, 1, seed + EVAL_SEED_OFFSET), training=False)
        # `eval_freq=1`: `EvalCallback._on_step` evaluates at every call it gets; `schedule` decides which.
        super().__init__(eval_env, trial, n_eval_episodes=settings.eval_episodes, eval_freq=1)
        self.settings = settings
        self.step_offset = step_offset
        self.earlier = dict(earlier or {})
        #: Timesteps between evaluations (and the run's checkpoints): a whole number of steps of every environment
        self.interval = max(config.n_timesteps // settings.n_evaluations // config.n_envs, 1) * config.n_envs
        self.schedule = TimestepSchedule(self.interval)
        self.n_reports = 0

    def _on_training_start(self) -> None:
        # A resumed run evaluates where an uninterrupted one would and carries over the evaluations before its
        # checkpoint (they are not redone).
        self.schedule.start(self.model.num_timesteps)
        self.n_reports = min(self.model.num_timesteps // self.interval, self.settings.n_evaluations)
        _carry_reports(self.trial, self.earlier, self.step_offset, self.step_offset + self.n_reports)

    def _on_step(self) -> bool:
        if self.schedule.due(self.num_timesteps):
            EvalCallback._on_step(self)
            # EvalCallback keeps the is_success of the evaluation's episodes (SB3 logs their mean as success_rate).
            value = objective_value(self.settings, float(self.last_mean_reward), success_rate(self._is_success_buffer))
            self.trial.report(value, self.step_offset + self.n_reports)
            self.n_reports += 1
            if self.trial.should_prune():
                self.is_pruned = True
                return False
        return True

    def _on_training_end(self) -> None:
        self.eval_env.close()


def _base_entry(settings: TuneSettings) -> dict[str, Any]:
    path = find_hyperparams_file(settings.conf_file) if settings.conf_file else packaged_hyperparams_file(settings.algo)
    entry, _ = select_entry(read_hyperparams_file(path), settings.env_id, path)
    return entry


def repair_journal(path: str) -> str | None:
    """
    Cut a torn last line off an Optuna journal file, so that a study whose last write was cut short (its
    process killed mid-write) can be continued.

    Optuna skips a last line without its newline when it reads the journal, but appends its next record to it,
    which makes a line that no later read can decode. Here, under the journal's own lock, a file that does not end
    with a newline is copied to ``{path}.torn-{n}`` (the first free ``n``) and truncated after its last newline; a
    warning names both files.

    :param path: The journal file (one that does not exist is left alone)
    :return: The copy of the torn file, or ``None`` where nothing was torn
    """
    if not os.path.isfile(path) or os.path.getsize(path) == 0:
        return None
    lock = JournalFileSymlinkLock(path)
    lock.acquire()
    try:
        with open(path, "rb+") as stream:
            text = stream.read()
            if not text or text.endswith(b"\n"):
                return None
            keep = text.rfind(b"\n") + 1
            copy = next(f"{path}.torn-{n}" for n in itertools.count() if not os.path.exists(f"{path}.torn-{n}"))
            shutil.copyfile(path, copy)
            stream.truncate(keep)
            stream.flush()
            os.fsync(stream.fileno())
    finally:
        lock.release()
    warnings.warn(
        f"{path}: its last line was cut short ({len(text) - keep} bytes without a newline, a write interrupted by a "
        f"crash); it is removed so that the study can continue, and the file as it was is kept in {copy}",
        stacklevel=2,
    )
    return copy


def hide_password(text: str, url: str) -> str:
    """
    ``text`` with the password of the database URL ``url`` (``mysql://user:password@host/db``) replaced by ``***``.

    :param text: A message that may show ``url`` or its password
    :param url: The URL
    """
    match = _PASSWORD.search(url)
    if match is None or not match.group(2):
        return text
    return text.replace(match.group(2), "***")


def check_storage(url: str) -> None:
    """
    Check ``--storage`` before anything is written: a journal file that is a regular file or does not exist yet, or a
    database URL of :data:`DATABASE_DIALECTS` (an SQLite file in an existing folder). Messages never show a password.

    :param url: The storage (a path, or a URL with ``://``)
    :raises HyperparamsError: naming ``--storage`` and what it accepts
    """
    shown = hide_password(url, url)
    accepted = f"accepted: a journal file (*.log) or a database URL ({', '.join(f'{d}://...' for d in DATABASE_DIALECTS)})"
    if "://" in url:
        dialect = url.partition("://")[0].partition("+")[0]
        if dialect not in DATABASE_DIALECTS:
            raise _refused("--storage", f"{shown}: unknown database {dialect!r}; {accepted}")
        if dialect != "sqlite":
            return
        path = url.partition("://")[2][1:]  # sqlite:///relative.db, sqlite:////absolute.db
        if path in ("", ":memory:"):
            raise _refused("--storage", f"{shown}: an SQLite database in memory cannot be shared or resumed; give a file")
        what = "SQLite database file"
    else:
        path, what = url, "journal file"
    folder = os.path.dirname(os.path.abspath(path))
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as error:
        raise _refused("--storage", f"{shown}: cannot be read as a {what}: {error.strerror}") from None
    if mode is not None and not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
        raise _refused("--storage", f"{shown} is {kind}; it must be a {what}; {accepted}")
    if what.startswith("SQLite") and not os.path.isdir(folder):
        raise _refused("--storage", f"{shown}: the folder {folder} of the {what} does not exist")


def _open_study(settings: TuneSettings, worker: int) -> optuna.Study:
    url = settings.storage_url()
    seed = settings.sampler_seed + worker
    sampler: optuna.samplers.BaseSampler = optuna.samplers.RandomSampler(seed=seed)
    if settings.sampler == "tpe":
        # Not the Zoo's `_create_sampler`: its TPE is multivariate, which would change the draws of committed studies.
        sampler = optuna.samplers.TPESampler(n_startup_trials=settings.n_startup_trials, seed=seed)
    # The Zoo's pruners (median after `n_evaluations // 3` warm-up steps, successive halving, none).
    zoo = cast(Any, SimpleNamespace(n_startup_trials=settings.n_startup_trials, n_evaluations=settings.n_evaluations))
    pruner = ExperimentManager._create_pruner(zoo, settings.pruner)
    try:
        storage: str | optuna.storages.BaseStorage = url  # a database: Optuna opens it (SQLAlchemy needed)
        if "://" not in url:
            os.makedirs(os.path.dirname(os.path.abspath(url)), exist_ok=True)
            storage = optuna.storages.JournalStorage(JournalFileBackend(url))
        return optuna.create_study(
            storage=storage,
            study_name=settings.name,
            sampler=sampler,
            pruner=pruner,
            direction="maximize",
            load_if_exists=True,
        )
    except ImportError as error:
        message = f"{url}: {error} (a journal file `*.log` needs nothing)"
        raise _refused("--storage", hide_password(message, url)) from None
    except Exception as error:
        # A file that is no Optuna journal (JSON it cannot decode, records without its keys), or the database's own
        # errors (SQLAlchemy's: no such server, access denied, not a database...).
        if "://" not in url and not isinstance(error, (ValueError, LookupError, TypeError)):
            raise
        message = f"{url}: cannot open the study: {type(error).__name__}: {error}"
        raise _refused("--storage", hide_password(message, url)) from None


def _fail_dead_trials(study: optuna.Study) -> None:
    """
    Mark as failed (and interrupted) the running trials of this machine whose worker process is gone. Optuna's
    heartbeats do this for a database (``RDBStorage`` only); the default journal file has none.
    """
    host = socket.gethostname()
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        worker = str(trial.user_attrs.get(_WORKER, ""))
        name, _, pid = worker.rpartition(":")
        if name == host and pid.isdigit() and not _alive(int(pid)):
            study._storage.set_trial_user_attr(trial._trial_id, _INTERRUPTED, True)
            study._storage.set_trial_state_values(trial._trial_id, TrialState.FAIL)
            print(f"Trial {trial.number} was interrupted (its worker {worker} is gone): failed, a new trial continues it")


def _continue_interrupted(study: optuna.Study) -> None:
    """Re-queue each interrupted trial not yet continued, with its parameters and attributes, as Optuna's
    ``RetryHeartbeatStaleTrialCallback`` re-queues a stale one (:func:`_continued_trial` then reuses its runs)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExperimentalWarning)
        retry = RetryHeartbeatStaleTrialCallback()
        trials = study.get_trials(deepcopy=False)
        continued = {retry.retry_history(trial)[-1] for trial in trials if retry.retry_history(trial)}
        for trial in trials:
            if trial.state == TrialState.FAIL and trial.user_attrs.get(_INTERRUPTED) and trial.number not in continued:
                retry(study, trial)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    return True


def _finished(study: optuna.Study) -> list[FrozenTrial]:
    return study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))


def _write_entry(path: str, env_id: str, entry: Mapping[str, Any], comment: str) -> None:
    text = f"# {comment}\n" + yaml.safe_dump({env_id: dict(entry)}, sort_keys=True)
    write_atomically(path, lambda stream: stream.write(text))


def _report(settings: TuneSettings, study: optuna.Study) -> TuneResult:
    attrs = [f"return_seed_{seed}" for seed in settings.seeds]
    attrs += [f"success_seed_{seed}" for seed in settings.seeds if settings.objective == "success"]
    rows = [
        {
            "number": trial.number,
            "state": trial.state.name,
            "value": "" if trial.value is None else round(trial.value, 3),
            "shipped": bool(trial.user_attrs.get(_SHIPPED)),
            "continues": trial.user_attrs.get(_CONTINUES, ""),
            "duration_s": "" if trial.duration is None else round(trial.duration.total_seconds(), 1),
            **{name: trial.user_attrs.get(name, "") for name in attrs},
            "params": yaml.safe_dump(trial.params, default_flow_style=True, width=10**6).strip(),
        }
        for trial in study.get_trials(deepcopy=False)
    ]
    csv_path = os.path.join(settings.study_dir, "trials.csv")

    def write_csv(stream: Any) -> None:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]) if rows else ["number"])
        writer.writeheader()
        writer.writerows(rows)

    write_atomically(csv_path, write_csv)
    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    if not complete:
        raise RuntimeError(f"no trial of study {settings.name} completed; see {csv_path}")
    best = max(complete, key=lambda trial: float(cast(float, trial.value)))
    print(f"{'trial':>5}  {'state':<8} {'value':>9}  params")
    for row in sorted(rows, key=lambda r: (r["state"] != "COMPLETE", -float(r["value"]) if r["value"] != "" else math.inf)):
        label = "shipped entry" if row["shipped"] else row["params"]
        print(f"{row['number']:>5}  {row['state']:<8} {row['value']!s:>9}  {label}")
    best_file = os.path.join(settings.study_dir, "best_hyperparams.yml")
    origin = "the shipped entry" if best.user_attrs.get(_SHIPPED) else f"trial {best.number}"
    quantity = "mean final return" if settings.objective == "return" else "mean final success rate"
    _write_entry(
        best_file,
        settings.env_id,
        read_yaml_file(str(best.user_attrs["hyperparams"]))[settings.env_id],
        f"Best of {len(_finished(study))} trials of study {settings.name} ({origin}): {quantity} "
        f"{best.value:.2f} over seeds {list(settings.seeds)}, {settings.n_timesteps or 'entry'} timesteps",
    )
    print(f"Best: {origin}, {quantity} {best.value:.2f}; hyperparameters in {best_file} (use with -conf)")
    return TuneResult(settings.study_dir, float(cast(float, best.value)), dict(best.params), best_file, len(_finished(study)))


__all__ = [
    "OBJECTIVE_NAMES",
    "PRUNER_NAMES",
    "SAMPLER_NAMES",
    "TrialEvalCallback",
    "TuneResult",
    "TuneSettings",
    "check_search_space",
    "check_success_reported",
    "objective_value",
    "trial_entry",
    "tune",
]
