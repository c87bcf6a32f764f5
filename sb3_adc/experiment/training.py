"""
Training runs in the RL-Zoo log layout: :func:`train` starts one, :func:`resume` continues one from its last
checkpoint, both checking their arguments before writing, then running :class:`~sb3_adc.experiment.manager.RunManager`
under the run's lock (a second process gets :class:`~sb3_adc.experiment.layout.RunLocked`).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from types import FrameType
from typing import Any

import gymnasium as gym
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.utils import check_for_correct_spaces
from stable_baselines3.common.vec_env import VecEnv

from sb3_adc.common.model_files import model_file_error, model_file_errors
from sb3_adc.common.safe_load import load_objects
from sb3_adc.common.spaces import ActionSpaceError
from sb3_adc.config import ExperimentConfig, HyperparamsError, load_hyperparams, resolve_entry
from sb3_adc.config.loader import read_yaml_file
from sb3_adc.config.schema import check_replay_buffer
from sb3_adc.experiment.callbacks import handling_signal
from sb3_adc.experiment.envs import make_run_envs, wrap_vec_env
from sb3_adc.experiment.evaluation import FinalEvaluation, success_unreported
from sb3_adc.experiment.layout import RunLayout, latest_run_dir, new_run_dir
from sb3_adc.experiment.manager import RunManager
from sb3_adc.experiment.restore import CheckpointContents, DamagedCheckpoint, read_checkpoint
from sb3_adc.experiment.settings import BEST_MODEL_METRICS, SettingsError, TrainSettings, write_yaml

#: Whether this process has received a SIGTERM handled as SIGINT (see :func:`sigterm_received`).
_SIGTERM_RECEIVED = threading.Event()


def sigterm_received() -> bool:
    """Whether this process has received a SIGTERM in the current :func:`sigterm_as_sigint` block (to pass on to workers)."""
    return _SIGTERM_RECEIVED.is_set()


def _sigterm_as_sigint(signum: int, frame: FrameType | None) -> None:
    """Call SIGINT's handler, or raise ``KeyboardInterrupt`` where SIGINT is ignored (a background job's)."""
    _SIGTERM_RECEIVED.set()
    handler = signal.getsignal(signal.SIGINT)
    if callable(handler):
        handler(signal.SIGINT, frame)
    else:
        raise KeyboardInterrupt


@contextmanager
def sigterm_as_sigint() -> Iterator[None]:
    """While the block runs, SIGTERM (Slurm, Kubernetes, ``kill``) is handled as SIGINT (main thread only)."""
    if threading.current_thread() is threading.main_thread():
        _SIGTERM_RECEIVED.clear()
    with handling_signal(signal.SIGTERM, _sigterm_as_sigint):
        yield


@dataclass
class TrainResult:
    """
    The outcome of a finished run.

    :param run_dir: The run's folder
    :param model_path: The final model
    :param final_evaluation: The final evaluation
    :param resumed_from: Timestep of the checkpoint this session started from (``None``: from scratch)
    """

    run_dir: str
    model_path: str
    final_evaluation: FinalEvaluation
    resumed_from: int | None = None


def train(settings: TrainSettings, callbacks: Sequence[BaseCallback] = (), trust_model_file: bool = False) -> TrainResult:
    """
    Train ``settings.algo`` on ``settings.env_id`` in a new run folder.

    :param settings: What to train and how to log it
    :param callbacks: Callbacks called after the run's own, e.g. a tuning trial's pruning; not saved with the run
    :param trust_model_file: Unpickle the model to continue (``settings.trained_agent``) and its files as SB3 does,
        running any code they hold (default: a safe load, raising ``UnsafeModelFileError`` for a file that needs more)
    :raises HyperparamsError: for invalid hyperparameters
    :raises SettingsError: for ``env_kwargs`` the environment rejects, an action space the algorithm cannot act in,
        or a ``trained_agent`` of another algorithm or for other spaces
    :raises ModelFileError: for a ``trained_agent`` that is not a readable model file
    :raises UnsafeModelFileError: for a ``trained_agent`` a safe load refuses
    :raises RunLocked: if another process is training in ``settings.run_dir``
    :raises RunInterrupted: on Ctrl-C, after saving a checkpoint (the others: before anything is written)
    """
    config = load_hyperparams(settings.algo, settings.env_id, settings.conf_file, settings.overrides, settings.n_timesteps)
    if settings.env_kwargs:
        config.env_kwargs.update(settings.env_kwargs)
        config.saved["env_kwargs"] = dict(config.env_kwargs)
    _check_before_run(settings, config, trust_model_file)
    run_dir = settings.run_dir or new_run_dir(settings.log_folder, settings.algo, settings.env_id)
    layout = RunLayout(run_dir, settings.env_id)
    with layout.lock():  # held for the run's whole life: one writer per run folder
        if os.path.exists(layout.params_dir):
            raise FileExistsError(
                f"{run_dir} already holds a run; continue it with resume (sb3-adc train --resume {run_dir})."
            )
        what = f"{settings.algo} on {settings.env_id} (seed {settings.seed}, {config.n_timesteps} timesteps"
        print(f"Training {what}, hyperparameters from {config.source}) in {run_dir}")
        settings = replace(settings, run_dir=run_dir)
        evaluation = RunManager(settings, config, callbacks=callbacks, trust_model_file=trust_model_file).run()
    return TrainResult(run_dir, layout.final_model, evaluation)


def resume(
    run_dir: str,
    n_timesteps: int | None = None,
    progress_bar: bool | None = None,
    verbose: int | None = None,
    callbacks: Sequence[BaseCallback] = (),
    trust_model_file: bool = False,
) -> TrainResult:
    """
    Continue a run from its latest checkpoint with its saved settings (a finished run: return its result), dropping
    the episodes and evaluations after it; without a checkpoint the run starts again in the same folder.

    :param run_dir: The run's folder
    :param n_timesteps: A new budget (for instance to train a finished run further); not below the checkpoint
    :param progress_bar: Show a progress bar (``None``: as saved)
    :param verbose: SB3 verbosity (``None``: as saved)
    :param callbacks: Callbacks called after the run's own, as in :func:`train` (not saved with the run)
    :param trust_model_file: Unpickle the checkpoint's files (or a model to continue) as SB3 does, running any code
    :raises FileNotFoundError: if ``run_dir`` holds no run
    :raises UnsafeModelFileError: for a checkpoint file that needs more than such a file holds (nothing changed)
    :raises RunLocked: if another process is training the run (before anything is written)
    :raises RunInterrupted: on Ctrl-C, after saving a checkpoint
    """
    changes: dict[str, Any] = {
        name: value for name, value in (("progress_bar", progress_bar), ("verbose", verbose)) if value is not None
    }
    settings = replace(TrainSettings.of_run(run_dir), run_dir=run_dir, **changes)
    layout = RunLayout(run_dir, settings.env_id)
    with layout.lock():  # held for the run's whole life, taken before anything of the run is read or changed
        config = resolve_entry(settings.algo, settings.env_id, read_yaml_file(layout.config), layout.config)
        contents = _latest_checkpoint(layout, trust_model_file)
        checkpoint = contents.checkpoint if contents is not None else None
        if n_timesteps is not None and n_timesteps != config.n_timesteps:
            reached = checkpoint.timesteps if checkpoint is not None else 0
            if n_timesteps < reached:
                problem = f"the run has a checkpoint at timestep {reached}: the budget cannot be {n_timesteps}"
                raise HyperparamsError("command line", "n_timesteps", problem)
            config.n_timesteps = config.saved["n_timesteps"] = n_timesteps
            write_yaml(layout.config, config.saved)
        if layout.is_finished():
            finished = FinalEvaluation.load(layout.final_evaluation)
            if finished.timesteps >= config.n_timesteps:
                print(f"{run_dir} has finished: {finished.summary()}")
                return TrainResult(run_dir, layout.final_model, finished, resumed_from=finished.timesteps)
            os.remove(layout.final_evaluation)
        evaluation = RunManager(settings, config, checkpoint, callbacks, contents, trust_model_file).run()
    return TrainResult(run_dir, layout.final_model, evaluation, resumed_from=checkpoint.timesteps if checkpoint else None)


def find_run(log_folder: str, algo: str, env_id: str) -> str:
    """
    The latest run of ``algo`` on ``env_id`` (the one ``sb3-adc train --resume`` continues).

    :param log_folder: The log folder
    :param algo: The algorithm's name
    :param env_id: The environment id
    :raises FileNotFoundError: if there is none
    """
    run_dir = latest_run_dir(log_folder, algo, env_id)
    if run_dir is None:
        raise FileNotFoundError(f"no run of {algo} on {env_id} in {os.path.join(log_folder, algo)} to resume.")
    return run_dir


def _latest_checkpoint(layout: RunLayout, trust: bool = False) -> CheckpointContents | None:
    """
    The newest checkpoint that can be resumed from, read. A newer damaged one is reported and its files are renamed
    ``*.damaged`` (no longer a checkpoint); one with a file that would run code raises ``UnsafeModelFileError``.
    """
    checkpoints = layout.checkpoints()
    for checkpoint in reversed(checkpoints):
        try:
            return read_checkpoint(checkpoint, trust)
        except DamagedCheckpoint as error:
            for path in filter(os.path.exists, checkpoint.files):
                os.replace(path, path + ".damaged")
            print(f"The checkpoint at timestep {checkpoint.timesteps} is damaged ({error}); its files are renamed *.damaged.")
    if checkpoints:
        print("No intact checkpoint is left: the run starts again from timestep 0.")
    return None


def _check_before_run(settings: TrainSettings, config: ExperimentConfig, trust_model_file: bool = False) -> None:
    """What only the environments tell, checked before the run folder is created."""
    settings.check_env_kwargs(config.env_id, config.env_kwargs)
    if settings.best_model_metric == "success" and settings.evaluation_interval(config.n_timesteps) > 0:
        probe = config.wrap_env(gym.make(config.env_id, **settings.evaluation_env_kwargs(config.env_kwargs)))
        problem = success_unreported(probe)
        if problem is not None:
            problem = f"'success' needs episodes that end with info['is_success'], but on {config.env_id} {problem}"
            raise SettingsError("best_model_metric", f"{problem}; accepted: {', '.join(BEST_MODEL_METRICS)}")
    env = wrap_vec_env(config, make_run_envs(config, 1, settings.seed), training=False)
    try:
        try:
            # The algorithm's own checks of the spaces, without building the networks or the replay buffer.
            model = config.algorithm_class(env=env, _init_setup_model=False, **config.model_kwargs)  # type: ignore[call-arg]
        except ActionSpaceError:
            raise
        except AssertionError as error:  # SB3's check of `supported_action_spaces`
            raise SettingsError("env_id", f"must be an environment {settings.algo} can act in: {error}", "--env") from None
        check_replay_buffer(model, config.source)  # its memory, before the run allocates it
        try:
            config.make_action_noise(env.action_space)
        except ValueError as error:
            raise HyperparamsError(config.source, "noise_type", str(error)) from None
        if settings.trained_agent is not None:
            _check_trained_agent(settings, config, env, trust_model_file)
    finally:
        env.close()


def _check_trained_agent(settings: TrainSettings, config: ExperimentConfig, env: VecEnv, trust: bool = False) -> None:
    """Read the model to continue (``-i``): a missing, damaged or refused file, another policy or other spaces fail."""
    path = str(settings.trained_agent)
    name = config.algorithm_class.__name__
    if not os.path.isfile(path):
        raise SettingsError("trained_agent", f"must be a model file saved by {settings.algo}: {path} does not exist")
    with model_file_errors(path, name):
        custom_objects = load_objects(path, trust)
        data, _, _ = load_from_zip_file(path, device="cpu", load_data=True, custom_objects=custom_objects)
    if data is None:
        raise model_file_error(f"{path} is not a readable {name} model file: it holds no model data")
    policy = config.model_kwargs.get("policy")
    aliases: dict[str, type] = getattr(config.algorithm_class, "policy_aliases", {})
    saved, expected = data.get("policy_class"), policy if isinstance(policy, type) else aliases.get(str(policy))
    if expected is not None and saved is not expected:
        saved_name = saved.__name__ if isinstance(saved, type) else repr(saved)
        problem = f"must be a model of --algo {settings.algo} ({name}, policy {expected.__name__})"
        raise SettingsError("trained_agent", f"{problem}: {path} holds a model with the policy {saved_name}")
    try:
        check_for_correct_spaces(env, data["observation_space"], data["action_space"])
    except ValueError as error:
        problem = f"must be a model for the spaces of {settings.env_id}: {path} is not ({error})"
        raise SettingsError("trained_agent", problem) from None
