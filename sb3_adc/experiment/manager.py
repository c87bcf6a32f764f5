"""
The experiment engine of every ``sb3-adc train``, benchmark run and tuning trial: :class:`RunManager`, the RL Zoo's
``ExperimentManager`` with what the Zoo lacks: hyperparameters of :mod:`sb3_adc.config`, exact and safe resume
(:mod:`~sb3_adc.experiment.continuation`, :mod:`~sb3_adc.experiment.restore`), atomic checkpoints and evaluations
(:mod:`~sb3_adc.experiment.callbacks`), a checkpoint on Ctrl-C, an error at the first NaN or inf, a final evaluation.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import warnings
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from rl_zoo3.exp_manager import ExperimentManager
from rl_zoo3.utils import ALGOS
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.logger import configure
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv, sync_envs_normalization
from tqdm import TqdmExperimentalWarning

from sb3_adc.config import ALGORITHMS, ExperimentConfig
from sb3_adc.experiment.callbacks import CheckpointSaver, EvaluationHistory, PeriodicEvalCallback, StopRequested, save_model
from sb3_adc.experiment.continuation import Continuation
from sb3_adc.experiment.divergence import NonFiniteValue, NonFiniteWeights, TrainingDiverged, check_finite_weights
from sb3_adc.experiment.envs import make_run_envs, wrap_vec_env
from sb3_adc.experiment.evaluation import FinalEvaluation
from sb3_adc.experiment.layout import Checkpoint, RunLayout
from sb3_adc.experiment.restore import (
    CheckpointContents,
    load_trained_agent,
    read_checkpoint,
    restore_records,
    saved_statistics,
)
from sb3_adc.experiment.settings import EVAL_SEED_OFFSET, TrainSettings, write_yaml


def register_algorithms() -> None:
    """Add sb3-adc's algorithms (:data:`~sb3_adc.config.algorithms.ALGORITHMS`) to the Zoo's ``ALGOS`` table."""
    for name in ALGORITHMS.names():
        ALGOS[name] = ALGORITHMS.resolve(name, "sb3_adc.experiment.manager", "algo")  # type: ignore[assignment]


class RunInterrupted(KeyboardInterrupt):
    """
    Training was interrupted (Ctrl-C); a checkpoint was saved first.

    :param run_dir: The run's folder (pass it to :func:`~sb3_adc.experiment.resume`)
    :param timesteps: The timestep of the checkpoint
    """

    def __init__(self, run_dir: str, timesteps: int):
        super().__init__(f"training interrupted at timestep {timesteps}; checkpoint saved in {run_dir}")
        self.run_dir = run_dir
        self.timesteps = timesteps


class RunManager(ExperimentManager):
    """
    The RL Zoo's ``ExperimentManager`` for one run in the layout of :mod:`sb3_adc.experiment.layout`.

    :param settings: What to train and how to log it (the run's ``args.yml``)
    :param config: The resolved hyperparameters (the run's ``config.yml``)
    :param checkpoint: The checkpoint to resume from (``None``: a new run, or a run started again from scratch)
    :param callbacks: Callbacks called after the run's own, e.g. the pruning callback of a tuning trial
    :param contents: The checkpoint's files, read already (``None``: read here)
    :param trust_model_file: Unpickle the model to continue (``-i``) and the checkpoint's files as SB3 does (any code)
    """

    def __init__(
        self,
        settings: TrainSettings,
        config: ExperimentConfig,
        checkpoint: Checkpoint | None = None,
        callbacks: Sequence[BaseCallback] = (),
        contents: CheckpointContents | None = None,
        trust_model_file: bool = False,
    ):
        register_algorithms()
        assert settings.run_dir is not None, "the run folder is chosen before the manager is made"
        self.settings = settings
        self.experiment = config
        self.layout = RunLayout(settings.run_dir, settings.env_id)
        self.checkpoint = checkpoint
        self.extra_callbacks = list(callbacks)
        self.trust_model_file = trust_model_file
        if checkpoint is not None and (contents is None or contents.checkpoint != checkpoint):
            contents = read_checkpoint(checkpoint, trust_model_file)
        self.contents = contents if checkpoint is not None else None
        super().__init__(
            args=argparse.Namespace(**dataclasses.asdict(settings)),
            algo=settings.algo,
            env_id=settings.env_id,
            log_folder=settings.log_folder,
            n_timesteps=config.n_timesteps,
            eval_freq=settings.evaluation_interval(config.n_timesteps),
            n_eval_episodes=settings.eval_episodes,
            save_freq=settings.checkpoint_interval(config.n_timesteps),
            env_kwargs=dict(config.env_kwargs),
            eval_env_kwargs=settings.evaluation_env_kwargs(config.env_kwargs),
            trained_agent=checkpoint.model if checkpoint is not None else settings.trained_agent or "",
            seed=settings.seed,
            verbose=settings.verbose,
            vec_env_type=settings.vec_env,
            n_eval_envs=settings.n_eval_envs,
            device=settings.device,
            config=config.source,
            show_progress=settings.progress_bar,
        )
        # The Zoo derives these from the log folder's next run id; the run's folder is already chosen.
        self.save_path = self.layout.run_dir
        self.params_path = self.layout.params_dir
        self.tensorboard_log = settings.tensorboard_folder()
        self.continue_training = bool(self.trained_agent)
        self.saver = CheckpointSaver(self.layout, max(self.save_freq, 0), settings.keep_checkpoints)
        self.train_env: VecEnv | None = None
        self.eval_env: VecEnv | None = None
        self.continuation: Continuation | None = None

    def read_hyperparameters(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """Resolved by :mod:`sb3_adc.config`: the Zoo receives Python objects."""
        saved = OrderedDict(sorted(self.experiment.saved.items()))
        return dict(saved), saved

    def _preprocess_hyperparams(
        self, hyperparams: dict[str, Any]
    ) -> tuple[dict[str, Any], Callable | None, list[BaseCallback], Callable | None]:
        config = self.experiment
        self.n_envs = config.n_envs
        self.n_timesteps = config.n_timesteps
        if config.normalize is not None:
            self.normalize = True
            self.normalize_kwargs = dict(config.normalize)
        self.frame_stack = config.frame_stack  # type: ignore[assignment]  # the Zoo declares it None
        env_wrapper = config.wrap_env if config.env_wrappers else None
        return dict(config.model_kwargs), env_wrapper, config.make_callbacks(), None

    def _preprocess_action_noise(
        self, hyperparams: dict[str, Any], saved_hyperparams: dict[str, Any], env: VecEnv
    ) -> dict[str, Any]:
        hyperparams = super()._preprocess_action_noise(hyperparams, saved_hyperparams, env)  # sets n_actions
        if self.experiment.noise is not None:
            hyperparams["action_noise"] = self.experiment.make_action_noise(env.action_space)
        return hyperparams

    def create_log_folder(self) -> None:
        """A new run writes ``config.yml`` and ``args.yml`` first; a resumed one keeps its records to its checkpoint."""
        super().create_log_folder()  # the Zoo's: makes the params folder
        if self.checkpoint is None and not os.path.isfile(self.layout.args):
            write_yaml(self.layout.config, self.experiment.saved)
            self.settings.save(self.layout.args)
        restore_records(self.layout, self.checkpoint, self.experiment.n_envs)

    def create_callbacks(self) -> None:
        """The periodic evaluation, then the checkpoints (a checkpoint includes its timestep's evaluation)."""
        own: list[BaseCallback] = []
        if self.eval_freq > 0:
            self.eval_env = self.create_envs(self.n_eval_envs, eval_env=True)
            history = EvaluationHistory.load(self.layout.evaluations)
            metric, seed = self.settings.best_model_metric, self.seed + EVAL_SEED_OFFSET
            evaluation = (self.eval_env, self.eval_freq, history, self.n_eval_episodes, self.save_path, self.verbose)
            own.append(PeriodicEvalCallback(*evaluation, best_model_metric=metric, eval_seed=seed))
        # The saver is always there: without periodic checkpoints it still saves the one of a stop (Ctrl-C).
        self.saver.eval_env = self.eval_env
        self.callbacks = [*own, self.saver, *self.callbacks, *self.extra_callbacks]

    def create_envs(self, n_envs: int, eval_env: bool = False, no_log: bool = False) -> VecEnv:
        """
        Training environments (seeded ``seed, seed + 1, ...``) write one monitor CSV each, appended to on resume;
        evaluation environments are seeded from ``seed + EVAL_SEED_OFFSET`` and never update ``VecNormalize``.

        :param n_envs: Number of environments
        :param eval_env: Evaluation environments rather than training ones
        :param no_log: Training environments without monitor files
        """
        config = self.experiment
        if eval_env:
            kwargs = self.settings.evaluation_env_kwargs(config.env_kwargs)
            venv = make_run_envs(config, n_envs, self.seed + EVAL_SEED_OFFSET, env_kwargs=kwargs)
            return wrap_vec_env(config, venv, training=False)
        start = self.checkpoint.timesteps if self.checkpoint is not None else 0
        venv = make_run_envs(
            config,
            n_envs,
            self.seed,
            monitor_dir=None if no_log else self.layout.run_dir,
            steps_offset=start // n_envs,
            append_monitor=self.checkpoint is not None,
            vec_env=self.settings.vec_env,
        )
        statistics = (
            self.contents.vecnormalize
            if self.contents is not None
            else saved_statistics(self.trained_agent, self.settings.env_id, self.trust_model_file)
        )
        self.train_env = wrap_vec_env(config, venv, training=True, statistics=statistics)
        return self.train_env

    def _load_pretrained_agent(self, hyperparams: dict[str, Any], env: VecEnv) -> BaseAlgorithm:
        """Resume from the run's checkpoint, or continue a saved model (``-i``) safely, from timestep 0."""
        algorithm_class: type[Any] = self.experiment.algorithm_class
        if self.contents is None:
            print(f"Continuing the training of {self.trained_agent}")
            # The Zoo's hook, with the safe load: the policy is the file's, the other hyperparameters the run's.
            kwargs = {key: value for key, value in hyperparams.items() if key not in ("policy", "policy_kwargs")}
            kwargs.update(
                env=env, seed=self.seed, tensorboard_log=self.tensorboard_log, verbose=self.verbose, device=self.device
            )
            return load_trained_agent(
                algorithm_class, self.trained_agent, self.settings.env_id, self.trust_model_file, **kwargs
            )
        model = self.contents.load_model(algorithm_class, env=env, device=self.device, tensorboard_log=self.tensorboard_log)
        model.verbose = self.verbose
        continuation = self.contents.continuation
        # Another checkpoint's (a file copied by hand) would continue another point of the run.
        if continuation is not None and continuation.timesteps == model.num_timesteps:
            self.continuation = continuation
        else:
            print(
                f"The checkpoint at timestep {self.contents.checkpoint.timesteps} has no continuation (taken by a "
                "second Ctrl-C, saved by an older version, or of a run whose state a continuation does not cover): the "
                "run goes on from a new random stream."
            )
            model.set_random_seed(self.seed + self.contents.checkpoint.timesteps)
        return model

    def _save_config(self, saved_hyperparams: dict[str, Any]) -> None:
        """Nothing more to write: ``create_log_folder`` wrote the configuration before anything could fail."""

    def learn(self, model: BaseAlgorithm) -> None:
        """
        Train to the budget. Ctrl-C stops after the step with an exact checkpoint, a second one at once with an
        inexact one, both raising :class:`RunInterrupted`; a NaN or inf raises ``TrainingDiverged``.

        :param model: The model of :meth:`setup_experiment`
        """
        if self.checkpoint is not None:
            print(f"Resuming {self.save_path} from timestep {self.checkpoint.timesteps} of {self.n_timesteps}")
        if self.tensorboard_log is None:
            # SB3's default logger would make an empty ``SB3-<date>`` folder in the temporary directory.
            model.set_logger(configure(self.save_path, ["stdout"] if model.verbose >= 1 else []))
        if self.continuation is not None:  # the checkpoint's continuation
            assert isinstance(model, OffPolicyAlgorithm), "only off-policy checkpoints hold a continuation"
            assert self.checkpoint is not None
            assert self.train_env is not None
            self.continuation.restore(model, self.eval_env, max(self.n_timesteps - model.num_timesteps, 0))
            if self.train_env.has_attr("set_total_steps"):  # the replay counted the episodes' steps again
                self.train_env.env_method("set_total_steps", self.checkpoint.timesteps // self.experiment.n_envs)
        try:
            with warnings.catch_warnings(), self.saver.stopping_on_ctrl_c():
                # SB3's progress bar uses tqdm's rich front-end, which warns that it is experimental.
                warnings.filterwarnings("ignore", category=TqdmExperimentalWarning)
                model.learn(
                    max(self.n_timesteps - model.num_timesteps, 0),
                    callback=self.callbacks,
                    reset_num_timesteps=self.checkpoint is None,
                    progress_bar=self.show_progress,
                )
            return
        except StopRequested as stop:
            saved, note = stop.timesteps, "; resuming continues the same run"
        except KeyboardInterrupt:
            if self.saver.model is None:
                self.saver.init_callback(model)
            try:
                saved, note = self.saver.save(exact=False).timesteps, ""
            except NonFiniteWeights as error:
                raise self._diverged(model, error) from None
        except (NonFiniteValue, NonFiniteWeights) as error:
            raise self._diverged(model, error) from None
        finally:
            if self.eval_env is not None:
                self.eval_env.close()
        print(f"\nInterrupted: checkpoint at timestep {saved} saved{note}.")
        print(f"Continue with: sb3-adc train --resume {self.save_path}")
        raise RunInterrupted(self.save_path, saved)

    def save_trained_model(self, model: BaseAlgorithm) -> None:
        """
        The final model and ``VecNormalize`` statistics (atomically), after a last checkpoint (to train further from).

        :param model: The trained model
        """
        try:
            check_finite_weights(model)
        except NonFiniteWeights as error:
            raise self._diverged(model, error) from None
        if self.save_freq > 0:
            checkpoints = self.layout.checkpoints()
            if not checkpoints or checkpoints[-1].timesteps != model.num_timesteps:
                self.saver.save()
        save_model(model, self.layout.final_model, self.layout.vecnormalize)

    def evaluate(self, model: BaseAlgorithm) -> FinalEvaluation:
        """
        The final evaluation (its file, written last, marks the run finished).

        :param model: The trained model
        """
        final_env = self.create_envs(1, eval_env=True)
        if model.get_vec_normalize_env() is not None and self.train_env is not None:
            sync_envs_normalization(self.train_env, final_env)
        successes: list[bool] = []

        def record_success(local: dict[str, Any], _: dict[str, Any]) -> None:  # as SB3's EvalCallback does
            if local["done"] and local["info"].get("is_success") is not None:
                successes.append(bool(local["info"]["is_success"]))

        try:
            n = self.settings.final_eval_episodes
            returns, lengths = evaluate_policy(model, final_env, n, return_episode_rewards=True, callback=record_success)
        finally:
            final_env.close()
            self._close()
        returns, lengths = [float(x) for x in np.atleast_1d(returns)], [int(x) for x in np.atleast_1d(lengths)]
        succeeded = successes if len(successes) == len(returns) else None
        evaluation = FinalEvaluation(
            self.algo, self.settings.env_id, self.seed, model.num_timesteps, returns, lengths, succeeded
        )
        evaluation.save(self.layout.final_evaluation)
        print(evaluation.summary())
        return evaluation

    def run(self) -> FinalEvaluation:
        """The whole run: the Zoo's ``setup_experiment``, ``learn`` and ``save_trained_model``, then :meth:`evaluate`."""
        setup = self.setup_experiment()
        assert setup is not None  # None only when optimizing, which sb3-adc does in sb3_adc.experiment.tuning
        model, _ = setup
        self.learn(model)
        self.save_trained_model(model)
        return self.evaluate(model)

    def _close(self) -> None:
        if self.train_env is not None:
            self.train_env.close()

    def _diverged(self, model: BaseAlgorithm, error: NonFiniteValue | NonFiniteWeights) -> TrainingDiverged:
        """The error that ends a run which met a NaN or inf."""
        self._close()
        timesteps = model.num_timesteps
        if isinstance(error, NonFiniteValue) and error.role == "training":
            timesteps += model.n_envs  # the step in progress: SB3 counts it once the environments return
        checkpoints = self.layout.checkpoints()
        source = error.source if isinstance(error, NonFiniteValue) else "weights"
        last = checkpoints[-1].timesteps if checkpoints else None
        return TrainingDiverged(self.save_path, timesteps, source, str(error), last)
