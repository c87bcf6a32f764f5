"""
Training runs in the RL-Zoo log layout, with periodic evaluation, checkpoints, resume and a final evaluation.

:func:`train` starts a run, :func:`resume` continues one from its last checkpoint (model, replay buffer,
``VecNormalize`` statistics, timestep count and exploration-noise state, evaluations so far). A run
interrupted with Ctrl-C (or SIGTERM, in :func:`sigterm_as_sigint`, as ``sb3-adc`` runs) saves a checkpoint first.
See :mod:`sb3_adc.experiment.layout` for the files. Both check what they are asked before a folder is written, then
hand the run to the engine,
:class:`~sb3_adc.experiment.manager.RunManager` (the RL Zoo's ``ExperimentManager``). They are the only doors to
the engine (``sb3-adc train``, the benchmark grids and the tuning trials all go through them), and each holds the
run's lock (:meth:`~sb3_adc.experiment.layout.RunLayout.lock`) from before it changes the folder until the final
evaluation is written: a second process on the same run gets
:class:`~sb3_adc.experiment.layout.RunLocked` at once.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from types import FrameType

import gymnasium as gym
import yaml
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.utils import check_for_correct_spaces
from stable_baselines3.common.vec_env import VecEnv

from sb3_adc.common.atomic import write_atomically
from sb3_adc.common.model_files import model_file_error, model_file_errors
from sb3_adc.common.safe_load import load_objects
from sb3_adc.common.spaces import ActionSpaceError
from sb3_adc.config import ExperimentConfig, HyperparamsError, load_hyperparams, resolve_entry
from sb3_adc.config.loader import read_yaml_file
from sb3_adc.config.schema import check_replay_buffer
from sb3_adc.experiment.envs import make_run_envs, wrap_vec_env
from sb3_adc.experiment.evaluation import FinalEvaluation, success_unreported
from sb3_adc.experiment.layout import RunLayout, latest_run_dir, new_run_dir
from sb3_adc.experiment.manager import RunManager
from sb3_adc.experiment.restore import CheckpointContents, DamagedCheckpoint, read_checkpoint
from sb3_adc.experiment.settings import BEST_MODEL_METRICS, SettingsError, TrainSettings

#: Whether this process has received a SIGTERM handled as SIGINT (see :func:`sigterm_received`).
_SIGTERM_RECEIVED = threading.Event()


def sigterm_received() -> bool:
    """
    Whether this process has received a SIGTERM in the current :func:`sigterm_as_sigint` block: a scheduler may
    signal only the main process (Kubernetes does), which then has to pass the signal on to its workers.
    """
    return _SIGTERM_RECEIVED.is_set()


def _sigterm_as_sigint(signum: int, frame: FrameType | None) -> None:
    """
    A SIGTERM handler that does what SIGINT (Ctrl-C) would do now: call the SIGINT handler in place (during
    training, the run's own, which stops after the step in progress with a checkpoint), or raise
    ``KeyboardInterrupt``, also where SIGINT is ignored: a shell script that starts a command in the background
    (``sb3-adc train ... &``) starts it with SIGINT ignored, and a scheduler's SIGTERM must still stop it.
    """
    _SIGTERM_RECEIVED.set()
    handler = signal.getsignal(signal.SIGINT)
    if callable(handler):
        handler(signal.SIGINT, frame)
    else:
        raise KeyboardInterrupt


@contextmanager
def sigterm_as_sigint() -> Iterator[None]:
    """
    While the block runs, SIGTERM is handled as SIGINT (Ctrl-C): a scheduler that stops a job with SIGTERM
    (Slurm, Kubernetes, ``kill``) gets a checkpoint and an orderly exit, as Ctrl-C does. The previous SIGTERM
    handler is restored after the block. Outside the main thread (where handlers cannot be set) nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _SIGTERM_RECEIVED.clear()
    previous = signal.signal(signal.SIGTERM, _sigterm_as_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@dataclass
class TrainResult:
    """
    The outcome of a finished run.

    :param run_dir: The run's folder
    :param model_path: The final model
    :param final_evaluation: The final evaluation
    :param resumed_from: Timestep of the checkpoint this session started from (``None``: started from scratch;
        equal to the budget when the run had already finished)
    """

    run_dir: str
    model_path: str
    final_evaluation: FinalEvaluation
    resumed_from: int | None = None


def train(settings: TrainSettings, callbacks: Sequence[BaseCallback] = (), trust_model_file: bool = False) -> TrainResult:
    """
    Train ``settings.algo`` on ``settings.env_id`` in a new run folder.

    :param settings: What to train and how to log it
    :param callbacks: Callbacks called after the run's own (evaluation, checkpoints), e.g. the pruning callback
        of a tuning trial; not saved with the run
    :param trust_model_file: Unpickle the model to continue (``settings.trained_agent``) and the files saved with it
        as SB3 does, which runs any code they hold (default: a safe load, which refuses a file that needs more than
        the classes it knows with :class:`~sb3_adc.common.safe_load.UnsafeModelFileError`)
    :raises HyperparamsError: for invalid hyperparameters (before anything is written)
    :raises SettingsError: for environment keyword arguments the environment rejects, an environment whose
        action space the algorithm cannot act in, or a ``trained_agent`` of another algorithm or for other spaces
        (before anything is written)
    :raises ModelFileError: for a ``trained_agent`` that is not a readable model file (before anything is written)
    :raises UnsafeModelFileError: for a ``trained_agent`` a safe load refuses (before anything is written)
    :raises RunLocked: if another process is training in ``settings.run_dir`` (before anything is written)
    :raises RunInterrupted: on Ctrl-C, after saving a checkpoint
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
        print(
            f"Training {settings.algo} on {settings.env_id} (seed {settings.seed}, {config.n_timesteps} timesteps, "
            f"hyperparameters from {config.source}) in {run_dir}"
        )
        run_settings = replace(settings, run_dir=run_dir)
        manager = RunManager(run_settings, config, callbacks=callbacks, trust_model_file=trust_model_file)
        evaluation = manager.run()
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
    Continue a run from its latest checkpoint (or return its result if it has finished).

    The settings and hyperparameters are those saved with the run (``args.yml``, ``config.yml``). Episodes and
    evaluations recorded after the checkpoint are dropped (that work is redone), the rest is kept. A run
    without checkpoint starts again from scratch in the same folder.

    :param run_dir: The run's folder
    :param n_timesteps: A new budget (for instance to train a finished run further); not below the checkpoint
    :param progress_bar: Show a progress bar (``None``: as saved)
    :param verbose: SB3 verbosity (``None``: as saved)
    :param callbacks: Callbacks called after the run's own, as in :func:`train` (not saved with the run)
    :param trust_model_file: Unpickle the checkpoint's files (and a model to continue, for a run without checkpoint)
        as SB3 does, which runs any code they hold (default: restricted unpicklers, which build only what sb3-adc
        writes in such files)
    :raises FileNotFoundError: if ``run_dir`` holds no run
    :raises UnsafeModelFileError: for a file of the checkpoint that needs more than such a file holds (a file
        planted in the run folder): refused, not run, before the run is changed
    :raises RunLocked: if another process is training the run (before anything is written)
    :raises RunInterrupted: on Ctrl-C, after saving a checkpoint
    """
    settings = TrainSettings.of_run(run_dir)
    settings = replace(
        settings,
        run_dir=run_dir,
        progress_bar=settings.progress_bar if progress_bar is None else progress_bar,
        verbose=settings.verbose if verbose is None else verbose,
    )
    layout = RunLayout(run_dir, settings.env_id)
    with layout.lock():  # held for the run's whole life, taken before anything of the run is read or changed
        return _resume_locked(layout, settings, n_timesteps, callbacks, trust_model_file)


def _resume_locked(
    layout: RunLayout,
    settings: TrainSettings,
    n_timesteps: int | None,
    callbacks: Sequence[BaseCallback],
    trust_model_file: bool,
) -> TrainResult:
    """:func:`resume`, under the run's lock."""
    run_dir = layout.run_dir
    config = resolve_entry(settings.algo, settings.env_id, read_yaml_file(layout.config), layout.config)
    contents = _latest_checkpoint(layout, trust_model_file)
    checkpoint = contents.checkpoint if contents is not None else None
    if n_timesteps is not None and n_timesteps != config.n_timesteps:
        reached = checkpoint.timesteps if checkpoint is not None else 0
        if n_timesteps < reached:
            raise HyperparamsError(
                "command line",
                "n_timesteps",
                f"the run has a checkpoint at timestep {reached}: the budget cannot be {n_timesteps}",
            )
        config.n_timesteps = n_timesteps
        config.saved["n_timesteps"] = n_timesteps
        write_atomically(layout.config, lambda stream: yaml.safe_dump(config.saved, stream, sort_keys=True))
    if layout.is_finished():
        finished = FinalEvaluation.load(layout.final_evaluation)
        if finished.timesteps >= config.n_timesteps:
            print(f"{run_dir} has finished: {finished.summary()}")
            return TrainResult(run_dir, layout.final_model, finished, resumed_from=finished.timesteps)
        os.remove(layout.final_evaluation)
    manager = RunManager(settings, config, checkpoint, callbacks, contents=contents, trust_model_file=trust_model_file)
    evaluation = manager.run()
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
    The newest checkpoint that can be resumed from, read (:func:`~sb3_adc.experiment.restore.read_checkpoint`:
    each file once, none running code unless ``trust``). A newer damaged one is reported and its files are renamed
    ``*.damaged`` (kept for inspection, no longer a checkpoint: pruning and later resumes pass over it); one with a
    file that would run code raises :class:`~sb3_adc.common.safe_load.UnsafeModelFileError`, the folder unchanged.
    """
    damaged = False
    for checkpoint in reversed(layout.checkpoints()):
        try:
            return read_checkpoint(checkpoint, trust)
        except DamagedCheckpoint as error:
            damage = str(error)
        damaged = True
        for path in checkpoint.files:
            if os.path.exists(path):
                os.replace(path, path + ".damaged")
        print(f"The checkpoint at timestep {checkpoint.timesteps} is damaged ({damage}); its files are renamed *.damaged.")
    if damaged:
        print("No intact checkpoint is left: the run starts again from timestep 0.")
    return None


def _expected_policy_class(config: ExperimentConfig) -> type | None:
    """The policy class a new model of the run would have (``None`` if the name is not one of the algorithm's)."""
    policy = config.model_kwargs.get("policy")
    if isinstance(policy, type):
        return policy
    aliases: dict[str, type] = getattr(config.algorithm_class, "policy_aliases", {})
    return aliases.get(str(policy))


def _check_before_run(settings: TrainSettings, config: ExperimentConfig, trust_model_file: bool = False) -> None:
    """
    What only the environments tell, checked before the run folder is created: keyword arguments they reject, an
    action space the algorithm (or its exploration noise) cannot act in, a model to continue (``-i``) of another
    algorithm or for other spaces.
    """
    settings.check_env_kwargs(config.env_id, config.env_kwargs)
    if settings.best_model_metric == "success" and settings.evaluation_interval(config.n_timesteps) > 0:
        probe = config.wrap_env(gym.make(config.env_id, **settings.evaluation_env_kwargs(config.env_kwargs)))
        problem = success_unreported(probe)
        if problem is not None:
            raise SettingsError(
                "best_model_metric",
                f"'success' needs episodes that end with info['is_success'], but on {config.env_id} {problem}; "
                f"accepted: {', '.join(BEST_MODEL_METRICS)}",
                "--best-model-metric",
            )
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
    """
    Read the model to continue (``-i``) before the run folder is created: a missing or damaged file, a model of
    another algorithm (another policy class), or one saved for other observation or action spaces than ``env``'s
    is an error, and so is (unless ``trust``) a file whose pickled entries a safe load refuses.
    """
    path = str(settings.trained_agent)
    name = config.algorithm_class.__name__
    if not os.path.isfile(path):
        raise SettingsError("trained_agent", f"must be a model file saved by {settings.algo}: {path} does not exist")
    with model_file_errors(path, name):
        custom_objects = load_objects(path, trust)
        data, _, _ = load_from_zip_file(path, device="cpu", load_data=True, custom_objects=custom_objects)
    if data is None:
        raise model_file_error(f"{path} is not a readable {name} model file: it holds no model data")
    saved, expected = data.get("policy_class"), _expected_policy_class(config)
    if expected is not None and saved is not expected:
        saved_name = saved.__name__ if isinstance(saved, type) else repr(saved)
        raise SettingsError(
            "trained_agent",
            f"must be a model of --algo {settings.algo} ({name}, policy {expected.__name__}): {path} holds a model "
            f"with the policy {saved_name}",
        )
    try:
        check_for_correct_spaces(env, data["observation_space"], data["action_space"])
    except ValueError as error:
        raise SettingsError(
            "trained_agent", f"must be a model for the spaces of {settings.env_id}: {path} is not ({error})"
        ) from None
