"""A trial of a study: its entry, its seeds' runs and the evaluations they report, and the continuation of a trial
that a Ctrl-C or a dead worker interrupted (with its hyperparameters and runs)."""

from __future__ import annotations

import math
import os
import socket
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
import optuna
import yaml
from optuna.exceptions import ExperimentalWarning
from optuna.storages import RetryHeartbeatStaleTrialCallback
from optuna.trial import FrozenTrial, TrialState
from rl_zoo3.callbacks import TrialEvalCallback as ZooTrialEvalCallback
from stable_baselines3.common.callbacks import EvalCallback

from sb3_adc.common.atomic import write_atomically
from sb3_adc.config import load_hyperparams
from sb3_adc.config.loader import apply_overrides, read_yaml_file
from sb3_adc.experiment.callbacks import TimestepSchedule
from sb3_adc.experiment.divergence import TrainingDiverged
from sb3_adc.experiment.envs import make_run_envs, wrap_vec_env
from sb3_adc.experiment.evaluation import FinalEvaluation, success_rate
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.manager import RunInterrupted
from sb3_adc.experiment.samplers import Space, sample
from sb3_adc.experiment.settings import EVAL_SEED_OFFSET, TrainSettings
from sb3_adc.experiment.training import resume, train
from sb3_adc.experiment.tuning_settings import TuneSettings, objective_value

#: User attributes: the shipped entry's trial, the worker running a trial, its folder (relative to the study's),
#: the trial a continuation continues, and a trial stopped by Ctrl-C or a dead worker.
SHIPPED, WORKER, TRIAL_DIR, CONTINUES, INTERRUPTED = "shipped", "worker", "trial_dir", "continues", "interrupted"


def objective(trial: optuna.Trial, settings: TuneSettings, base: dict[str, Any]) -> float:
    """
    Run one trial (the shipped entry, drawn hyperparameters, or the continuation of an interrupted trial).

    :param trial: The Optuna trial
    :param settings: The study's settings
    :param base: The starting entry
    :return: The trial's value: the mean over its seeds of the final evaluations' objective
    :raises optuna.TrialPruned: for a pruned or diverged run, or a non-finite value
    """
    trial.set_user_attr(WORKER, f"{socket.gethostname()}:{os.getpid()}")
    trial.set_user_attr(INTERRUPTED, False)  # a continuation inherits the attributes of the trial it continues
    params = {}
    if not trial.user_attrs.get(SHIPPED):
        params = sample(settings.algo, Space(trial, {**base, **settings.overrides}, settings.overrides, settings.search_space))
    entry = trial_entry(base, params, settings.overrides, settings.n_timesteps)
    earlier, folder = _continued_trial(trial, settings, entry)
    trial_dir = os.path.join(settings.study_dir, folder)
    os.makedirs(trial_dir, exist_ok=True)
    trial.set_user_attr(TRIAL_DIR, folder)
    hyperparams_file = os.path.join(trial_dir, "hyperparams.yml")
    if earlier is None:
        write_entry(hyperparams_file, settings.env_id, entry, f"trial {trial.number} of study {settings.name}")
    trial.set_user_attr("hyperparams", hyperparams_file)
    values = []
    try:
        for index, seed in enumerate(settings.seeds):
            final = _run_seed(trial, settings, trial_dir, seed, index * settings.n_evaluations, earlier)
            trial.set_user_attr(f"return_seed_{seed}", final.mean_return)
            if settings.objective == "success":
                trial.set_user_attr(f"success_seed_{seed}", final.success_rate)
            values.append(objective_value(settings, final.mean_return, final.success_rate))
    except RunInterrupted:
        trial.set_user_attr(INTERRUPTED, True)  # the next invocation continues it (continue_interrupted)
        raise
    value = float(np.mean(values))
    if not math.isfinite(value):
        raise optuna.TrialPruned(f"non-finite return {value}")
    return value


def _run_seed(
    trial: optuna.Trial, settings: TuneSettings, trial_dir: str, seed: int, first: int, earlier: Mapping[int, float] | None
) -> FinalEvaluation:
    """Train (or, in a continued trial, resume or reuse) the run of one seed, reporting from step ``first``."""
    run_dir, hyperparams_file = os.path.join(trial_dir, f"seed_{seed}"), os.path.join(trial_dir, "hyperparams.yml")
    layout = RunLayout(run_dir, settings.env_id)
    if earlier is not None and layout.is_finished():
        _carry_reports(trial, earlier, first, first + settings.n_evaluations)
        return resume(run_dir).final_evaluation
    callback = TrialEvalCallback(trial, settings, hyperparams_file, seed, step_offset=first, earlier=earlier)
    try:
        if earlier is not None and os.path.isdir(layout.params_dir):
            result = resume(run_dir, callbacks=[callback])
        else:
            same = ("algo", "env_id", "n_timesteps", "log_folder", "final_eval_episodes", "device", "verbose")
            run_settings = TrainSettings(
                **{key: getattr(settings, key) for key in same},
                seed=seed,
                conf_file=hyperparams_file,
                env_kwargs=dict(settings.env_kwargs),
                eval_env_kwargs=dict(settings.eval_env_kwargs),
                run_dir=run_dir,
                eval_freq=-1,
                save_freq=callback.interval,  # a checkpoint at every evaluation: a continuation resumes from there
                keep_checkpoints=1,
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
    """The reported evaluations and folder of the interrupted trial this one continues with the same entry; else
    ``None`` and the trial's own folder (a changed starting entry or ``-params`` start afresh)."""
    own = f"trial_{trial.number}"
    trials = trial.study.get_trials(deepcopy=False)
    history = _retry_history(trials[trial.number])
    if not history:
        return None, own
    previous = trials[history[-1]]
    trial.set_user_attr(CONTINUES, previous.number)
    folder = str(previous.user_attrs.get(TRIAL_DIR, f"trial_{previous.number}"))
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


def _retry_history(trial: FrozenTrial) -> list[int]:
    """Optuna's ``retry_history`` of a trial (without its ``ExperimentalWarning``)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExperimentalWarning)
        return RetryHeartbeatStaleTrialCallback.retry_history(trial)


def trial_entry(
    base: Mapping[str, Any], params: Mapping[str, Any], overrides: Mapping[str, Any], n_timesteps: int | None = None
) -> dict[str, Any]:
    """
    A trial's entry: the starting entry, the sampled values, then the fixed overrides, merged as ``-params``.

    :param base: The starting entry
    :param params: The sampled values
    :param overrides: Values fixed in every trial (``-params``)
    :param n_timesteps: The study's training budget (``None``: the entry's), written into the entry so that its
        file trains with ``-conf`` for as long as the trial did
    """
    entry = apply_overrides(base, {**params, **overrides})
    if n_timesteps is not None:
        entry["n_timesteps"] = n_timesteps
    return entry


class TrialEvalCallback(ZooTrialEvalCallback):
    """
    The RL Zoo's ``TrialEvalCallback``, reporting the study's objective ``n_evaluations`` times per run (by timesteps)
    on the trial entry's evaluation environment, with the report steps of the seeds end to end.

    :param trial: The Optuna trial
    :param settings: The study's settings
    :param hyperparams_file: The trial's hyperparameter file
    :param seed: The run's seed
    :param step_offset: Report step of this run's first evaluation
    :param earlier: The evaluations an interrupted trial reported (by step), carried over up to a resumed checkpoint
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
        # A resumed run evaluates where an uninterrupted one would, carrying over the evaluations before its checkpoint.
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


def continue_interrupted(study: optuna.Study) -> None:
    """
    Re-queue each interrupted trial not yet continued, with its parameters and attributes, with Optuna's
    ``RetryHeartbeatStaleTrialCallback`` (:func:`objective` then reuses its runs). First, a running trial of this
    machine whose worker process is gone is failed as interrupted: Optuna's heartbeats do this for a database only
    (``RDBStorage``, after a grace period), the default journal file has none.

    :param study: The study
    """
    host = socket.gethostname()
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        worker = str(trial.user_attrs.get(WORKER, ""))
        name, _, pid = worker.rpartition(":")
        if name == host and pid.isdigit() and not _alive(int(pid)):
            study._storage.set_trial_user_attr(trial._trial_id, INTERRUPTED, True)
            study._storage.set_trial_state_values(trial._trial_id, TrialState.FAIL)
            print(f"Trial {trial.number} was interrupted (its worker {worker} is gone): failed, a new trial continues it")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExperimentalWarning)
        retry = RetryHeartbeatStaleTrialCallback()
    trials = study.get_trials(deepcopy=False)
    continued = {history[-1] for history in map(_retry_history, trials) if history}
    for trial in trials:
        if trial.state == TrialState.FAIL and trial.user_attrs.get(INTERRUPTED) and trial.number not in continued:
            retry(study, trial)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    return True


def write_entry(path: str, env_id: str, entry: Mapping[str, Any], comment: str) -> None:
    """
    Write a hyperparameter file of one entry (usable with ``-conf``) under a comment line.

    :param path: The file
    :param env_id: The entry's environment id
    :param entry: The entry
    :param comment: The comment line
    """
    text = f"# {comment}\n" + yaml.safe_dump({env_id: dict(entry)}, sort_keys=True)
    write_atomically(path, lambda stream: stream.write(text))
