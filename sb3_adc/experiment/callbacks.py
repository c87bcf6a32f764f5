"""
SB3's ``EvalCallback`` and ``CheckpointCallback`` as a resumable run needs them: on the timestep count, every file
written atomically (:mod:`sb3_adc.common.atomic`; :mod:`sb3_adc.experiment.restore` reads them back).
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from types import FrameType
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.save_util import save_to_pkl
from stable_baselines3.common.vec_env import VecEnv

from sb3_adc.common.atomic import atomic_path, write_atomically
from sb3_adc.experiment.continuation import Continuation
from sb3_adc.experiment.divergence import check_finite_weights
from sb3_adc.experiment.evaluation import success_rate
from sb3_adc.experiment.layout import CHECKPOINT_PREFIX, Checkpoint, DamagedFileError, RunLayout, remove_files
from sb3_adc.experiment.manifest import write_manifest


@dataclass
class EvaluationHistory:
    """
    The periodic evaluations of a run (the content of ``evaluations.npz``).

    :param timesteps: Timestep of each evaluation
    :param results: Episode returns of each evaluation
    :param ep_lengths: Episode lengths of each evaluation
    :param successes: Each evaluation's ``info["is_success"]`` per episode (empty where not reported)
    """

    timesteps: list[int] = field(default_factory=list)
    results: list[list[float]] = field(default_factory=list)
    ep_lengths: list[list[int]] = field(default_factory=list)
    successes: list[list[bool]] = field(default_factory=list)

    @classmethod
    def load(cls, path: str) -> EvaluationHistory:
        """
        Read an ``evaluations.npz`` (an empty history if the file does not exist).

        :param path: The file
        :raises DamagedFileError: if the file is truncated or does not hold an evaluation history
        """
        if not os.path.isfile(path):
            return cls()
        try:
            with np.load(path) as data:
                history = cls(
                    timesteps=[int(step) for step in data["timesteps"]],
                    results=[[float(value) for value in row] for row in data["results"]],
                    ep_lengths=[[int(value) for value in row] for row in data["ep_lengths"]],
                    successes=[[bool(value) for value in row] for row in data["successes"]] if "successes" in data else [],
                )
        except (OSError, ValueError, EOFError, KeyError, TypeError, zipfile.BadZipFile) as error:
            raise DamagedFileError(path, f"{type(error).__name__}: {error}") from error
        if not len(history.timesteps) == len(history.results) == len(history.ep_lengths):
            raise DamagedFileError(path, "timesteps, results and ep_lengths have different lengths")
        if len(history.successes) != len(history.timesteps):  # runs resumed before the history kept them
            history.successes = []
        return history

    def until(self, timesteps: int) -> EvaluationHistory:
        """
        The evaluations made at or before a timestep.

        :param timesteps: The last timestep kept
        """
        keep = [index for index, step in enumerate(self.timesteps) if step <= timesteps]
        return EvaluationHistory(
            [self.timesteps[i] for i in keep],
            [self.results[i] for i in keep],
            [self.ep_lengths[i] for i in keep],
            [self.successes[i] for i in keep] if self.successes else [],
        )

    def save(self, path: str) -> None:
        """
        Write the history as ``evaluations.npz`` (the format of SB3's ``EvalCallback``), atomically.

        :param path: The file
        """
        arrays: dict[str, Any] = {"timesteps": self.timesteps, "results": self.results, "ep_lengths": self.ep_lengths}
        if self.successes:
            arrays["successes"] = self.successes
        write_atomically(path, lambda stream: np.savez(stream, **arrays), binary=True)

    def success_rates(self) -> list[float | None]:
        """
        Each evaluation's share of episodes that ended with ``info["is_success"]`` (SB3's ``eval/success_rate``):
        ``None`` for an evaluation whose episodes did not report it, an empty list if the history kept none.
        """
        return [success_rate(row) for row in self.successes]


class TimestepSchedule:
    """
    When a callback acts: at every multiple of ``every`` of the model's timestep count, so that a resumed run acts
    when an uninterrupted one would (SB3's callbacks count their own calls, which restart at 0 on resume).

    :param every: Timesteps between two actions
    """

    def __init__(self, every: int):
        self.every = every
        self.next = every

    def start(self, num_timesteps: int) -> None:
        """
        Act next at the first multiple of :attr:`every` after a timestep count.

        :param num_timesteps: The model's count
        """
        self.next = (num_timesteps // self.every + 1) * self.every

    def due(self, num_timesteps: int) -> bool:
        """
        Whether the callback acts at this timestep count (then the next one is scheduled).

        :param num_timesteps: The model's count now
        """
        if num_timesteps < self.next:
            return False
        self.start(num_timesteps)
        return True


class PeriodicEvalCallback(EvalCallback):
    """
    SB3's ``EvalCallback`` on a :class:`TimestepSchedule`, started from the evaluations of a resumed run (kept in
    ``evaluations.npz``; ``best_model.zip`` only when beaten), both files written atomically.

    ``best_model_metric="success"`` keeps the model of the highest success rate (ties: the higher mean return), every
    evaluation on the same episodes (the environments seeded with ``eval_seed`` first), so that models are compared
    on equal terms rather than on SB3's ever-new episodes.

    :param eval_env: The evaluation environments
    :param every: Evaluate every this many timesteps (all training environments together)
    :param history: Evaluations made before (a resumed run)
    :param n_eval_episodes: Episodes per evaluation
    :param run_dir: Folder of ``evaluations.npz`` and ``best_model.zip``
    :param verbose: 1 to print each evaluation
    :param best_model_metric: ``return`` (SB3's rule) or ``success`` (see above)
    :param eval_seed: Seed of the evaluation environments before each evaluation (``best_model_metric="success"``)
    """

    def __init__(
        self,
        eval_env: VecEnv,
        every: int,
        history: EvaluationHistory,
        n_eval_episodes: int,
        run_dir: str,
        verbose: int = 0,
        best_model_metric: str = "return",
        eval_seed: int = 0,
    ):
        super().__init__(
            eval_env,
            n_eval_episodes=n_eval_episodes,
            eval_freq=1,
            log_path=run_dir,
            best_model_save_path=None,  # `EvalCallback` would write best_model.zip in place: `_on_step` saves it
            deterministic=True,
            verbose=verbose,
        )
        self.schedule = TimestepSchedule(every)
        self.evaluations_file = os.path.join(run_dir, "evaluations.npz")
        self.best_model_file = os.path.join(run_dir, "best_model.zip")
        self.evaluations_timesteps = list(history.timesteps)
        self.evaluations_results = list(history.results)
        self.evaluations_length = list(history.ep_lengths)
        self.evaluations_successes = list(history.successes)
        mean_returns = [float(np.mean(row)) for row in history.results]
        self.best_mean_reward = max(mean_returns, default=self.best_mean_reward)
        self.best_model_metric = best_model_metric
        self.eval_seed = eval_seed
        scores = [(rate, mean) for rate, mean in zip(history.success_rates(), mean_returns, strict=False) if rate is not None]
        self.best_success: tuple[float, float] | None = max(scores, default=None)

    def _init_callback(self) -> None:
        super()._init_callback()
        # `self.num_timesteps` is only updated at the first step: read the model's count (a resumed run's).
        self.schedule.start(self.model.num_timesteps)

    def _on_step(self) -> bool:
        if not self.schedule.due(self.num_timesteps):
            return True
        best_before = self.best_mean_reward
        if self.best_model_metric == "success":
            self.eval_env.seed(self.eval_seed)  # the same episodes at every evaluation
        # `EvalCallback` writes the whole history with `np.savez(self.log_path, ...)`: point it to the temporary file.
        with atomic_path(self.evaluations_file) as temporary:
            self.log_path = temporary
            continue_training = super()._on_step()
        if self._improved(best_before):
            with atomic_path(self.best_model_file) as temporary:
                self.model.save(temporary)
        return continue_training

    def _improved(self, best_mean_reward_before: float) -> bool:
        """Whether the evaluation just made is the best so far by :attr:`best_model_metric`."""
        if self.best_model_metric == "return":
            return self.best_mean_reward > best_mean_reward_before
        rate = success_rate(self._is_success_buffer)
        if rate is None:
            raise ValueError("best_model_metric 'success': the evaluation's episodes ended without info['is_success']")
        score = (rate, float(self.last_mean_reward))
        improved = self.best_success is None or score > self.best_success
        self.best_success = score if improved else self.best_success
        return improved


def save_model(model: BaseAlgorithm, path: str, vecnormalize_path: str) -> None:
    """
    Save a model and its ``VecNormalize`` statistics (where it has them), each atomically, the model last.

    :param model: The model
    :param path: Its zip
    :param vecnormalize_path: The statistics' pickle
    """
    vec_normalize = model.get_vec_normalize_env()
    if vec_normalize is not None:
        with atomic_path(vecnormalize_path) as temporary:
            vec_normalize.save(temporary)
    with atomic_path(path) as temporary:
        model.save(temporary)


class StopRequested(Exception):
    """
    Raised by :class:`CheckpointSaver` once the checkpoint of a step is saved, when a stop was requested (Ctrl-C).

    :param timesteps: The checkpoint's timestep
    """

    def __init__(self, timesteps: int):
        super().__init__(f"stopped at timestep {timesteps}")
        self.timesteps = timesteps


class CheckpointSaver(CheckpointCallback):
    """
    SB3's ``CheckpointCallback`` (its file names) on a :class:`TimestepSchedule`, each file written atomically, the
    ``keep`` latest checkpoints kept, never a model with non-finite weights, and with each checkpoint, where one is
    exact, its :class:`~sb3_adc.experiment.continuation.Continuation`. Give it after the evaluation callback. Setting
    :attr:`stop_requested` (Ctrl-C) makes the next step save a checkpoint and raise :class:`StopRequested`.

    :param layout: The run's paths
    :param every: Timesteps between checkpoints (0: none but those of a requested stop)
    :param keep: Number of checkpoints kept (older ones are deleted)
    :param eval_env: The run's evaluation environments, whose episodes the continuation keeps too (``None``: none)
    """

    def __init__(self, layout: RunLayout, every: int, keep: int, eval_env: VecEnv | None = None):
        super().__init__(max(every, 1), layout.run_dir, CHECKPOINT_PREFIX, save_replay_buffer=True, save_vecnormalize=True)
        self.layout = layout
        self.keep = keep
        self.periodic = every > 0
        self.schedule = TimestepSchedule(max(every, 1))
        self.eval_env = eval_env
        self.stop_requested = False

    def _init_callback(self) -> None:
        self.schedule.start(self.model.num_timesteps)

    def _on_step(self) -> bool:
        due = self.periodic and self.schedule.due(self.num_timesteps)
        if due or self.stop_requested:
            checkpoint = self.save(step_locals=self.locals)
            if self.stop_requested:
                raise StopRequested(checkpoint.timesteps)
        return True

    def save(self, step_locals: dict[str, Any] | None = None, exact: bool = True) -> Checkpoint:
        """
        Save a checkpoint at the current timestep now.

        :param step_locals: ``collect_rollouts``' locals when saving inside a step, ``None`` between steps
        :param exact: Whether the run can be continued exactly from here (``False``: no continuation is saved)
        :raises NonFiniteWeights: if the model's weights hold NaN or inf (nothing is written)
        """
        check_finite_weights(self.model)
        self.num_timesteps = self.model.num_timesteps
        checkpoint = self.layout.checkpoint(self.num_timesteps)
        remove_files((checkpoint.manifest, checkpoint.continuation))  # those of an earlier checkpoint of this timestep
        # The model last: a checkpoint counts once its model zip exists.
        if hasattr(self.model, "save_replay_buffer") and getattr(self.model, "replay_buffer", None) is not None:
            with atomic_path(checkpoint.replay_buffer) as temporary:
                self.model.save_replay_buffer(temporary)
        continuation = Continuation.capture(self.model, self.eval_env, step_locals) if exact else None
        if continuation is not None:
            with atomic_path(checkpoint.continuation) as temporary:
                save_to_pkl(temporary, continuation)
        save_model(self.model, checkpoint.model, checkpoint.vecnormalize)
        write_manifest(checkpoint)
        for old in self.layout.checkpoints()[: -self.keep]:
            old.remove()
        return checkpoint

    def stopping_on_ctrl_c(self) -> contextlib.AbstractContextManager[None]:
        """
        While the block runs, the first Ctrl-C (SIGINT) sets :attr:`stop_requested`; a second one raises
        ``KeyboardInterrupt`` at once.
        """

        def request_stop(signum: int, frame: FrameType | None) -> None:
            if self.stop_requested:
                raise KeyboardInterrupt
            self.stop_requested = True
            print("\nCtrl-C: stopping after this step with a checkpoint (Ctrl-C again stops at once).", flush=True)

        return handling_signal(signal.SIGINT, request_stop)


@contextlib.contextmanager
def handling_signal(signum: int, handler: Callable[[int, FrameType | None], Any]) -> Iterator[None]:
    """
    ``handler`` handles ``signum`` while the block runs, the previous handler after it. Outside the main thread,
    where Python sets no handlers, nothing changes.

    :param signum: The signal
    :param handler: Its handler
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signum, handler)
    try:
        yield
    finally:
        signal.signal(signum, previous)
