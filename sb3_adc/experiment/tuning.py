"""
Hyperparameter tuning with Optuna (``sb3-adc train -optimize``), on the same engine as every other run.

The RL Zoo's ``hyperparameters_optimization`` with its pruners and ``TrialEvalCallback``: a trial's value is the final
evaluation's mean return (``objective="return"``) or success rate (``"success"``). Differences, each for a reason: the
first trial is the shipped entry (a tuned entry is at least as good on the tuning seeds); a trial trains several seeds
and can evaluate on other environment keywords (``eval_env_kwargs``); ``search_space`` adds or replaces choices per
key; an interrupted trial is re-queued with its hyperparameters and keeps its runs; and the budget is exactly
``n_trials`` finished trials whatever the ``--n-jobs``, so that tuned algorithms are compared fairly.

Files, under ``{log_folder}/tuning/{study_name}/``: ``study.log`` (the Optuna journal), ``trial_N/hyperparams.yml``,
``trial_N/seed_S/`` (runs), ``trials.csv``, ``best_hyperparams.yml`` (for ``-conf``) and ``.lock``: one command at a
time tunes a study kept in a journal file; a ``--storage`` database is shared on purpose, without a lock.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import multiprocessing
import os
import time
from dataclasses import dataclass
from multiprocessing.sharedctypes import Synchronized
from typing import Any, cast

import gymnasium as gym
import optuna
import torch as th
import yaml
from optuna.trial import FrozenTrial, TrialState

from sb3_adc.common.atomic import write_atomically
from sb3_adc.config import load_hyperparams
from sb3_adc.config.loader import (
    find_hyperparams_file,
    packaged_hyperparams_file,
    read_hyperparams_file,
    read_yaml_file,
    select_entry,
)
from sb3_adc.experiment.invocations import InvocationJournal, read_invocations
from sb3_adc.experiment.settings import check_env_kwargs
from sb3_adc.experiment.tuning_settings import TuneSettings, check_search_space, check_success_reported
from sb3_adc.experiment.tuning_storage import check_storage, open_study, repair_journal, study_lock
from sb3_adc.experiment.tuning_trials import CONTINUES, SHIPPED, continue_interrupted, objective, write_entry


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
    wall_time_s: float = 0.0


def tune(settings: TuneSettings) -> TuneResult:
    """
    Run (or continue) a study until it holds ``settings.n_trials`` finished trials.

    :param settings: What to tune
    :raises HyperparamsError: for invalid settings or hyperparameters, before any trial runs
    :raises RunLocked: if another command tunes the study in its folder (a journal storage), before anything is written
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
        if "://" not in settings.storage_url():
            repair_journal(settings.storage_url())
        study = open_study(settings, worker=0)  # a database it cannot open stops here, before the study's folder is made
        os.makedirs(settings.study_dir, exist_ok=True)
        continue_interrupted(study)
        if not any(trial.user_attrs.get(SHIPPED) and trial.state != TrialState.FAIL for trial in study.trials):
            study.enqueue_trial({}, user_attrs={SHIPPED: True})
        finished_before = len(_finished(study))
        remaining = settings.n_trials - finished_before - len(study.get_trials(False, (TrialState.RUNNING,)))
        start = time.perf_counter()
        print(
            f"Tuning {settings.algo} on {settings.env_id}: study {settings.name} in {settings.study_dir}, "
            f"{finished_before} of {settings.n_trials} trials finished, seeds {list(settings.seeds)}, "
            f"{settings.n_jobs} worker(s)"
        )
        # The invocations that train the study keep their time in its folder's invocations.json (a heartbeat, kept
        # after Ctrl-C or a kill): the study's wall time is their sum. One that only reports adds none.
        if remaining > 0:
            journal = InvocationJournal([(settings.study_dir, [settings.algo], settings.n_trials)], settings.n_jobs, "local")
            with journal:
                _run_trials(settings, base, remaining)
                result = _report(settings, open_study(settings, worker=0))
                for _ in range(result.n_finished - finished_before):
                    journal.record(settings.study_dir, "trained")
        else:
            result = _report(settings, open_study(settings, worker=0))
        print(f"Tuning took {time.perf_counter() - start:.0f} s")
        wall_time = sum(entry["wall_time_s"] for entry in read_invocations([settings.study_dir]))
        return dataclasses.replace(result, wall_time_s=round(wall_time, 1))


def _run_trials(settings: TuneSettings, base: dict[str, Any], remaining: int) -> None:
    """Run ``remaining`` trials, taken one at a time by whichever of the study's workers is free."""
    # Optuna's MaxTrialsCallback (the Zoo's budget) counts the study's trials after each one ends, and two workers
    # ending at once can both start one more: it overshoots by up to n_jobs - 1 trials. A shared count, taken under
    # a lock, is exact.
    context = multiprocessing.get_context("spawn")
    tickets = context.Value("i", remaining)
    workers = [
        context.Process(target=_work, args=(settings, base, k, tickets), name=f"tuning-worker-{k}")
        for k in range(min(settings.n_jobs, remaining))
    ]
    if len(workers) == 1:
        _work(settings, base, 0, tickets)
        return
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    failed = [worker.name for worker in workers if worker.exitcode != 0]
    if failed:
        raise RuntimeError(f"{', '.join(failed)} stopped with an error; run the same command again to continue")


def _work(settings: TuneSettings, base: dict[str, Any], worker: int, tickets: Synchronized[int]) -> None:
    """One worker: run trials of the study while ``tickets`` (shared by the workers) has trials left to run."""
    th.set_num_threads(1)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = open_study(settings, worker)
    while True:
        with tickets.get_lock():
            if tickets.value <= 0:
                return
            tickets.value -= 1
        study.optimize(lambda trial: objective(trial, settings, base), n_trials=1, catch=())


def _base_entry(settings: TuneSettings) -> dict[str, Any]:
    path = find_hyperparams_file(settings.conf_file) if settings.conf_file else packaged_hyperparams_file(settings.algo)
    entry, _ = select_entry(read_hyperparams_file(path), settings.env_id, path)
    return entry


def _finished(study: optuna.Study) -> list[FrozenTrial]:
    return study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))


def _report(settings: TuneSettings, study: optuna.Study) -> TuneResult:
    attrs = [f"return_seed_{seed}" for seed in settings.seeds]
    attrs += [f"success_seed_{seed}" for seed in settings.seeds if settings.objective == "success"]
    rows = [
        {
            "number": trial.number,
            "state": trial.state.name,
            "value": "" if trial.value is None else round(trial.value, 3),
            "shipped": bool(trial.user_attrs.get(SHIPPED)),
            "continues": trial.user_attrs.get(CONTINUES, ""),
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
    origin = "the shipped entry" if best.user_attrs.get(SHIPPED) else f"trial {best.number}"
    quantity = "mean final return" if settings.objective == "return" else "mean final success rate"
    n_finished = len(_finished(study))
    comment = f"Best of {n_finished} trials of study {settings.name} ({origin}): {quantity} {best.value:.2f} over seeds "
    comment += f"{list(settings.seeds)}, {settings.n_timesteps or 'entry'} timesteps"
    write_entry(best_file, settings.env_id, read_yaml_file(str(best.user_attrs["hyperparams"]))[settings.env_id], comment)
    print(f"Best: {origin}, {quantity} {best.value:.2f}; hyperparameters in {best_file} (use with -conf)")
    return TuneResult(settings.study_dir, float(cast(float, best.value)), dict(best.params), best_file, n_finished)


__all__ = ["TuneResult", "TuneSettings", "tune"]
