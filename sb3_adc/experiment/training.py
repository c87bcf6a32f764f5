"""
Training runs in the RL-Zoo log layout, with periodic evaluation, checkpoints, resume and a final evaluation.

:func:`train` starts a run, :func:`resume` continues one from its last checkpoint (model, replay buffer,
``VecNormalize`` statistics, timestep count and exploration-noise state, evaluations so far). A run
interrupted with Ctrl-C saves a checkpoint first. See :mod:`sb3_adc.experiment.layout` for the files.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.utils import check_for_correct_spaces
from stable_baselines3.common.vec_env import VecEnv, sync_envs_normalization
from tqdm import TqdmExperimentalWarning

from sb3_adc.common.atomic import atomic_path, write_atomically
from sb3_adc.common.model_files import model_file_error, model_file_errors
from sb3_adc.common.spaces import ActionSpaceError
from sb3_adc.config import ExperimentConfig, HyperparamsError, load_hyperparams, resolve_entry
from sb3_adc.config.loader import read_yaml_file
from sb3_adc.experiment.callbacks import CheckpointSaver, EvaluationHistory, PeriodicEvalCallback, checkpoint_damage
from sb3_adc.experiment.divergence import (
    NonFiniteValue,
    NonFiniteWeights,
    TrainingDiverged,
    check_finite_weights,
)
from sb3_adc.experiment.envs import make_vec_env, wrap_vec_env
from sb3_adc.experiment.evaluation import FinalEvaluation, evaluate_final
from sb3_adc.experiment.layout import Checkpoint, DamagedFileError, RunLayout, latest_run_dir, new_run_dir
from sb3_adc.experiment.monitor_files import truncate_monitor
from sb3_adc.experiment.settings import EVAL_SEED_OFFSET, SettingsError, TrainSettings


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


class RunInterrupted(KeyboardInterrupt):
    """
    Training was interrupted (Ctrl-C); a checkpoint was saved first.

    :param run_dir: The run's folder (pass it to :func:`resume`)
    :param timesteps: The timestep of the checkpoint
    """

    def __init__(self, run_dir: str, timesteps: int):
        super().__init__(f"training interrupted at timestep {timesteps}; checkpoint saved in {run_dir}")
        self.run_dir = run_dir
        self.timesteps = timesteps


def train(settings: TrainSettings, callbacks: Sequence[BaseCallback] = ()) -> TrainResult:
    """
    Train ``settings.algo`` on ``settings.env_id`` in a new run folder.

    :param settings: What to train and how to log it
    :param callbacks: Callbacks called after the run's own (evaluation, checkpoints), e.g. the pruning callback
        of a tuning trial; not saved with the run
    :raises HyperparamsError: for invalid hyperparameters (before anything is written)
    :raises SettingsError: for environment keyword arguments the environment rejects, an environment whose
        action space the algorithm cannot act in, or a ``trained_agent`` of another algorithm or for other spaces
        (before anything is written)
    :raises ModelFileError: for a ``trained_agent`` that is not a readable model file (before anything is written)
    :raises RunInterrupted: on Ctrl-C, after saving a checkpoint
    """
    config = load_hyperparams(settings.algo, settings.env_id, settings.conf_file, settings.overrides, settings.n_timesteps)
    if settings.env_kwargs:
        config.env_kwargs.update(settings.env_kwargs)
        config.saved["env_kwargs"] = dict(config.env_kwargs)
    _check_before_run(settings, config)
    run_dir = settings.run_dir or new_run_dir(settings.log_folder, settings.algo, settings.env_id)
    layout = RunLayout(run_dir, settings.env_id)
    if os.path.exists(layout.params_dir):
        raise FileExistsError(f"{run_dir} already holds a run; continue it with resume (sb3-adc train --resume {run_dir}).")
    os.makedirs(layout.params_dir)
    write_atomically(layout.config, lambda stream: yaml.safe_dump(config.saved, stream, sort_keys=True))
    replace(settings, run_dir=run_dir).save(layout.args)
    print(
        f"Training {settings.algo} on {settings.env_id} (seed {settings.seed}, {config.n_timesteps} timesteps, "
        f"hyperparameters from {config.source}) in {run_dir}"
    )
    return _run(layout, settings, config, checkpoint=None, extra_callbacks=callbacks)


def resume(
    run_dir: str, n_timesteps: int | None = None, progress_bar: bool | None = None, verbose: int | None = None
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
    :raises FileNotFoundError: if ``run_dir`` holds no run
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
    config = resolve_entry(settings.algo, settings.env_id, read_yaml_file(layout.config), layout.config)
    checkpoint = _latest_checkpoint(layout)
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
    return _run(layout, settings, config, checkpoint=checkpoint)


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


def _latest_checkpoint(layout: RunLayout) -> Checkpoint | None:
    """
    The newest checkpoint that can be resumed from. A newer damaged one is reported and its files are renamed
    ``*.damaged`` (kept for inspection, no longer a checkpoint: pruning and later resumes pass over it).
    """
    damaged = False
    for checkpoint in reversed(layout.checkpoints()):
        damage = checkpoint_damage(checkpoint)
        if damage is None:
            return checkpoint
        damaged = True
        for path in (checkpoint.model, checkpoint.replay_buffer, checkpoint.vecnormalize):
            if os.path.exists(path):
                os.replace(path, path + ".damaged")
        print(f"The checkpoint at timestep {checkpoint.timesteps} is damaged ({damage}); its files are renamed *.damaged.")
    if damaged:
        print("No intact checkpoint is left: the run starts again from timestep 0.")
    return None


def _run(
    layout: RunLayout,
    settings: TrainSettings,
    config: ExperimentConfig,
    checkpoint: Checkpoint | None,
    extra_callbacks: Sequence[BaseCallback] = (),
) -> TrainResult:
    start = checkpoint.timesteps if checkpoint is not None else 0
    _restore_records(layout, config, start)
    train_env = make_vec_env(
        config,
        config.n_envs,
        settings.seed,
        monitor_files=[layout.monitor_file(rank) for rank in range(config.n_envs)],
        steps_offset=start // config.n_envs,
        append_monitor=checkpoint is not None,
        vec_env=settings.vec_env,
    )
    statistics = _statistics_to_load(settings, checkpoint)
    train_env = wrap_vec_env(config, train_env, training=True, statistics=statistics)
    model = _load_or_build(settings, config, train_env, checkpoint)
    eval_env = _evaluation_env(config, settings, settings.n_eval_envs)

    saver = CheckpointSaver(layout, max(settings.checkpoint_interval(config.n_timesteps), 1), settings.keep_checkpoints)
    callbacks: list[BaseCallback] = []
    eval_every = settings.evaluation_interval(config.n_timesteps)
    if eval_every > 0:
        history = EvaluationHistory.load(layout.evaluations)
        callbacks.append(
            PeriodicEvalCallback(eval_env, eval_every, history, settings.eval_episodes, layout.run_dir, settings.verbose)
        )
    if settings.checkpoint_interval(config.n_timesteps) > 0:
        callbacks.append(saver)
    callbacks.extend(config.make_callbacks())
    callbacks.extend(extra_callbacks)

    if checkpoint is not None:
        print(f"Resuming {layout.run_dir} from timestep {start} of {config.n_timesteps}")
    try:
        with warnings.catch_warnings():
            # SB3's progress bar uses tqdm's rich front-end, which warns that it is experimental.
            warnings.filterwarnings("ignore", category=TqdmExperimentalWarning)
            model.learn(
                max(config.n_timesteps - model.num_timesteps, 0),
                callback=callbacks,
                reset_num_timesteps=checkpoint is None,
                progress_bar=settings.progress_bar,
            )
    except KeyboardInterrupt:
        if saver.model is None:
            saver.init_callback(model)
        try:
            saved = saver.save()
        except NonFiniteWeights as error:
            raise _diverged(layout, model, error) from None
        print(f"\nInterrupted: checkpoint at timestep {saved.timesteps} saved.")
        print(f"Continue with: sb3-adc train --resume {layout.run_dir}")
        raise RunInterrupted(layout.run_dir, saved.timesteps) from None
    except (NonFiniteValue, NonFiniteWeights) as error:
        train_env.close()
        raise _diverged(layout, model, error) from None
    finally:
        eval_env.close()

    try:
        check_finite_weights(model)
    except NonFiniteWeights as error:
        train_env.close()
        raise _diverged(layout, model, error) from None
    if settings.checkpoint_interval(config.n_timesteps) > 0:
        checkpoints = layout.checkpoints()
        if not checkpoints or checkpoints[-1].timesteps != model.num_timesteps:
            # The replay buffer at the end, for training the run further (resume with a larger budget).
            saver.save()
    with atomic_path(layout.final_model) as temporary:
        model.save(temporary)
    vec_normalize = model.get_vec_normalize_env()
    if vec_normalize is not None:
        with atomic_path(layout.vecnormalize) as temporary:
            vec_normalize.save(temporary)
    final_env = _evaluation_env(config, settings, 1)
    if vec_normalize is not None:
        sync_envs_normalization(train_env, final_env)
    try:
        evaluation = evaluate_final(
            model, final_env, settings.final_eval_episodes, settings.algo, settings.env_id, settings.seed
        )
    finally:
        final_env.close()
        train_env.close()
    evaluation.save(layout.final_evaluation)
    print(evaluation.summary())
    return TrainResult(
        layout.run_dir, layout.final_model, evaluation, resumed_from=checkpoint.timesteps if checkpoint else None
    )


def _diverged(layout: RunLayout, model: BaseAlgorithm, error: NonFiniteValue | NonFiniteWeights) -> TrainingDiverged:
    """The error that ends a run which met a NaN or inf: where, and which checkpoint is left to resume from."""
    timesteps = model.num_timesteps
    if isinstance(error, NonFiniteValue) and error.role == "training":
        timesteps += model.n_envs  # the step in progress: SB3 counts it once the environments return
    checkpoints = layout.checkpoints()
    source = error.source if isinstance(error, NonFiniteValue) else "weights"
    last = checkpoints[-1].timesteps if checkpoints else None
    return TrainingDiverged(layout.run_dir, timesteps, source, str(error), last)


def _restore_records(layout: RunLayout, config: ExperimentConfig, start: int) -> None:
    """Keep the evaluations and episodes up to ``start`` (the checkpoint); from scratch, remove them all."""
    if start == 0:
        for path in [layout.evaluations, layout.best_model, *layout.monitor_files()]:
            if os.path.exists(path):
                os.remove(path)
        return
    try:
        history = EvaluationHistory.load(layout.evaluations)
    except DamagedFileError as error:
        # The evaluations up to the checkpoint cannot be recovered; the run goes on without them.
        print(f"{error}; the evaluations before timestep {start} are lost and the history restarts after it.")
        history = EvaluationHistory()
    history.until(start).save(layout.evaluations)
    for path in layout.monitor_files():
        truncate_monitor(path, start // config.n_envs)


def _load_or_build(
    settings: TrainSettings, config: ExperimentConfig, env: VecEnv, checkpoint: Checkpoint | None
) -> BaseAlgorithm:
    algorithm_class: type[Any] = config.algorithm_class
    tensorboard_log = settings.tensorboard_folder()
    if checkpoint is None and settings.trained_agent is not None:
        return _load_trained_agent(settings, config, env)
    if checkpoint is None:
        kwargs = dict(config.model_kwargs)
        if config.noise is not None:
            kwargs["action_noise"] = config.make_action_noise(env.action_space)
        return algorithm_class(
            env=env,
            seed=settings.seed,
            verbose=settings.verbose,
            device=settings.device,
            tensorboard_log=tensorboard_log,
            **kwargs,
        )
    model = algorithm_class.load(checkpoint.model, env=env, device=settings.device, tensorboard_log=tensorboard_log)
    model.verbose = settings.verbose
    if os.path.isfile(checkpoint.replay_buffer) and hasattr(model, "load_replay_buffer"):
        model.load_replay_buffer(checkpoint.replay_buffer)
    # A new random stream: the resumed part does not replay the first part's draws.
    model.set_random_seed(settings.seed + checkpoint.timesteps)
    return model


def _evaluation_env(config: ExperimentConfig, settings: TrainSettings, n_envs: int) -> VecEnv:
    env_kwargs = settings.evaluation_env_kwargs(config.env_kwargs)
    env = make_vec_env(config, n_envs, settings.seed + EVAL_SEED_OFFSET, env_kwargs=env_kwargs)
    return wrap_vec_env(config, env, training=False)


def _saved_with(model_path: str, env_id: str) -> tuple[str | None, str | None]:
    """
    The replay buffer and ``VecNormalize`` statistics saved with a model (``None`` where absent): a checkpoint's
    own (``rl_model_{t}_steps.zip``), else the RL Zoo's ``replay_buffer.pkl`` beside the model and
    ``{env_name}/vecnormalize.pkl``.
    """
    layout = RunLayout(os.path.dirname(os.path.abspath(model_path)), env_id)
    files = (os.path.join(layout.run_dir, "replay_buffer.pkl"), layout.vecnormalize)
    for checkpoint in layout.checkpoints():
        if os.path.abspath(checkpoint.model) == os.path.abspath(model_path):
            files = (checkpoint.replay_buffer, checkpoint.vecnormalize)
    replay_buffer, statistics = (path if os.path.isfile(path) else None for path in files)
    return replay_buffer, statistics


def _statistics_to_load(settings: TrainSettings, checkpoint: Checkpoint | None) -> str | None:
    """The ``VecNormalize`` statistics the run starts from: the checkpoint's, or those of the trained agent."""
    if checkpoint is not None:
        return checkpoint.vecnormalize if os.path.isfile(checkpoint.vecnormalize) else None
    if settings.trained_agent is not None:
        return _saved_with(settings.trained_agent, settings.env_id)[1]
    return None


def _expected_policy_class(config: ExperimentConfig) -> type | None:
    """The policy class a new model of the run would have (``None`` if the name is not one of the algorithm's)."""
    policy = config.model_kwargs.get("policy")
    if isinstance(policy, type):
        return policy
    aliases: dict[str, type] = getattr(config.algorithm_class, "policy_aliases", {})
    return aliases.get(str(policy))


def _check_before_run(settings: TrainSettings, config: ExperimentConfig) -> None:
    """
    What only the environments tell, checked before the run folder is created: keyword arguments they reject, an
    action space the algorithm (or its exploration noise) cannot act in, a model to continue (``-i``) of another
    algorithm or for other spaces.
    """
    settings.check_env_kwargs(config.env_id, config.env_kwargs)
    env = wrap_vec_env(config, make_vec_env(config, 1, settings.seed), training=False)
    try:
        try:
            # The algorithm's own checks of the spaces, without building the networks or the replay buffer.
            config.algorithm_class(env=env, _init_setup_model=False, **config.model_kwargs)  # type: ignore[call-arg]
        except ActionSpaceError:
            raise
        except AssertionError as error:  # SB3's check of `supported_action_spaces`
            raise SettingsError("env_id", f"must be an environment {settings.algo} can act in: {error}", "--env") from None
        try:
            config.make_action_noise(env.action_space)
        except ValueError as error:
            raise HyperparamsError(config.source, "noise_type", str(error)) from None
        if settings.trained_agent is not None:
            _check_trained_agent(settings, config, env)
    finally:
        env.close()


def _check_trained_agent(settings: TrainSettings, config: ExperimentConfig, env: VecEnv) -> None:
    """
    Read the model to continue (``-i``) before the run folder is created: a missing or damaged file, a model of
    another algorithm (another policy class), or one saved for other observation or action spaces than ``env``'s
    is an error.
    """
    path = str(settings.trained_agent)
    name = config.algorithm_class.__name__
    if not os.path.isfile(path):
        raise SettingsError("trained_agent", f"must be a model file saved by {settings.algo}: {path} does not exist")
    with model_file_errors(path, name):
        data, _, _ = load_from_zip_file(path, device="cpu", load_data=True)
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


def _load_trained_agent(settings: TrainSettings, config: ExperimentConfig, env: VecEnv) -> BaseAlgorithm:
    """
    The model to continue (``-i``), loaded as the RL Zoo does: its policy and weights, the run's other
    hyperparameters, and the replay buffer saved with it, if any. Its timestep count starts again at 0: the run
    trains ``n_timesteps`` more.
    """
    path = str(settings.trained_agent)
    algorithm_class: type[Any] = config.algorithm_class
    kwargs = {key: value for key, value in config.model_kwargs.items() if key not in ("policy", "policy_kwargs")}
    if config.noise is not None:
        kwargs["action_noise"] = config.make_action_noise(env.action_space)
    print(f"Continuing the training of {path}")
    with model_file_errors(path, algorithm_class.__name__):
        model = algorithm_class.load(
            path,
            env=env,
            device=settings.device,
            seed=settings.seed,
            verbose=settings.verbose,
            tensorboard_log=settings.tensorboard_folder(),
            **kwargs,
        )
    replay_buffer, _ = _saved_with(path, settings.env_id)
    if replay_buffer is not None and hasattr(model, "load_replay_buffer"):
        print(f"Loading the replay buffer {replay_buffer}")
        model.load_replay_buffer(replay_buffer)
    model.num_timesteps = 0
    return model
