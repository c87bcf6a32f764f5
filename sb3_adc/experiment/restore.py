"""
Restoring a run without running code from its files: its checkpoint (:func:`read_checkpoint`) or a model to continue
(the Zoo's ``-i``, :func:`load_trained_agent`), and its records cut back to the checkpoint (:func:`restore_records`).
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.save_util import load_from_pkl
from stable_baselines3.common.vec_env import VecNormalize
from stable_baselines3.her.her_replay_buffer import HerReplayBuffer

from sb3_adc.common.model_files import loading_model, model_file_error, model_file_errors
from sb3_adc.common.safe_load import (
    CONTINUATION_GLOBALS,
    REPLAY_BUFFER_GLOBALS,
    VEC_NORMALIZE_GLOBALS,
    DamagedEntryError,
    UnsafeModelFileError,
    load_objects,
    restricted_load,
    safe_objects,
)
from sb3_adc.experiment.callbacks import EvaluationHistory
from sb3_adc.experiment.continuation import CONTINUATION_VERSION, Continuation
from sb3_adc.experiment.layout import Checkpoint, DamagedFileError, RunLayout, remove_files
from sb3_adc.experiment.manifest import manifest_damage
from sb3_adc.experiment.monitor_files import truncate_monitor


class DamagedCheckpoint(ValueError):
    """A checkpoint that cannot be resumed from: a file is missing, truncated or corrupted (the message says which)."""


@dataclass
class CheckpointContents:
    """
    A checkpoint read by :func:`read_checkpoint`, each file once.

    :param checkpoint: Its files
    :param model_objects: The ``custom_objects`` that load its model zip without unpickling anything (``None``: trusted)
    :param replay_buffer: Its replay buffer (``None``: none)
    :param vecnormalize: Its ``VecNormalize`` statistics, without environments (``None``: none)
    :param continuation: Its continuation (``None``: none, or one of another version)
    """

    checkpoint: Checkpoint
    model_objects: dict[str, Any] | None = None
    replay_buffer: Any = None
    vecnormalize: VecNormalize | None = None
    continuation: Continuation | None = None

    def load_model(self, algorithm_class: type[Any], **kwargs: Any) -> BaseAlgorithm:
        """
        The checkpoint's model, with its replay buffer.

        :param algorithm_class: The run's algorithm
        :param kwargs: Keyword arguments of its ``load``
        """
        with loading_model():
            model = algorithm_class.load(self.checkpoint.model, custom_objects=self.model_objects, **kwargs)
        if self.replay_buffer is not None and hasattr(model, "load_replay_buffer"):
            _use_replay_buffer(model, self.replay_buffer)
        return model


def read_checkpoint(checkpoint: Checkpoint, trust: bool = False) -> CheckpointContents:
    """
    Read a checkpoint to resume from: its files must match its manifest (if any, checked before unpickling), its model
    zip must pass its CRC check and hold ``data``, its pickles must unpickle, each with its allow-list (no code runs).

    :param checkpoint: The checkpoint
    :param trust: Unpickle its files as SB3 does, which can run any code they hold
    :raises DamagedCheckpoint: for a missing model zip or a damaged file, naming it
    :raises UnsafeModelFileError: for a file that needs a class or function outside its allow-list (not damage)
    """
    name = os.path.basename(checkpoint.model)
    if not os.path.isfile(checkpoint.model):
        raise DamagedCheckpoint(f"{name} is missing")
    damage = manifest_damage(checkpoint) if os.path.isfile(checkpoint.manifest) else None
    if damage is not None:
        raise DamagedCheckpoint(damage)
    try:
        with zipfile.ZipFile(checkpoint.model) as archive:
            broken, names = archive.testzip(), archive.namelist()
    except (OSError, zipfile.BadZipFile, EOFError, ValueError) as error:
        raise DamagedCheckpoint(f"{name} does not open as a zip ({error})") from None
    if broken is not None:
        raise DamagedCheckpoint(f"{name}: member {broken} is corrupted")
    if "data" not in names:
        raise DamagedCheckpoint(f"{name} holds no SB3 model (no `data` member)")
    contents = CheckpointContents(checkpoint)
    if not trust:
        try:
            contents.model_objects = safe_objects(checkpoint.model)
        except DamagedEntryError as error:
            raise DamagedCheckpoint(str(error)) from None
        except UnsafeModelFileError:
            raise
        except (OSError, zipfile.BadZipFile, KeyError, ValueError) as error:  # JSON and UTF-8 errors are ValueErrors
            raise DamagedCheckpoint(f"{name}: its `data` does not read ({type(error).__name__}: {error})") from None
    pickles = {  # each file's allow-list, what it holds, and the class it must be
        checkpoint.replay_buffer: (REPLAY_BUFFER_GLOBALS, "a replay buffer", ReplayBuffer),
        checkpoint.vecnormalize: (VEC_NORMALIZE_GLOBALS, "VecNormalize statistics", VecNormalize),
        checkpoint.continuation: (CONTINUATION_GLOBALS, "a continuation", object),
    }
    loaded: dict[str, Any] = {}
    for path, (allowed, what, _) in pickles.items():
        if not os.path.isfile(path):
            continue
        try:
            loaded[path] = load_from_pkl(path) if trust else restricted_load(path, allowed, what)
        except UnsafeModelFileError:
            raise
        except Exception as error:  # unpickling a damaged file can raise almost anything
            raise DamagedCheckpoint(f"{os.path.basename(path)} does not unpickle ({type(error).__name__}: {error})") from None
    for path, (_, what, kind) in pickles.items():  # once all are read: an unsafe file is refused, whatever the others
        if loaded.get(path) is not None and not isinstance(loaded[path], kind):
            raise DamagedCheckpoint(f"{os.path.basename(path)} holds no {what.removeprefix('a ')}")
    contents.replay_buffer = loaded.get(checkpoint.replay_buffer)
    contents.vecnormalize = loaded.get(checkpoint.vecnormalize)
    continuation = loaded.get(checkpoint.continuation)
    if isinstance(continuation, Continuation) and getattr(continuation, "version", None) == CONTINUATION_VERSION:
        contents.continuation = continuation
    return contents


def checkpoint_damage(checkpoint: Checkpoint, trust: bool = False) -> str | None:
    """
    Why a checkpoint cannot be resumed from, or ``None`` if it can: its manifest's check, or :func:`read_checkpoint`.

    :param checkpoint: The checkpoint
    :param trust: As for :func:`read_checkpoint`
    :raises UnsafeModelFileError: for a file outside the allow-lists, as :func:`read_checkpoint` (without a manifest)
    """
    if os.path.isfile(checkpoint.model) and os.path.isfile(checkpoint.manifest):
        return manifest_damage(checkpoint)
    try:
        read_checkpoint(checkpoint, trust)
    except DamagedCheckpoint as error:
        return str(error)
    return None


def _use_replay_buffer(model: OffPolicyAlgorithm, replay_buffer: ReplayBuffer) -> None:
    """SB3's ``load_replay_buffer`` (``truncate_last_traj=True``) for a buffer unpickled already (safely)."""
    model.replay_buffer = replay_buffer
    if not hasattr(replay_buffer, "handle_timeout_termination"):  # SB3 < 2.1's buffers, as SB3 reads them
        replay_buffer.handle_timeout_termination = False
        replay_buffer.timeouts = np.zeros_like(replay_buffer.dones)
    if isinstance(replay_buffer, HerReplayBuffer):  # only from a trusted file: not in the restricted allow-list
        assert model.env is not None, "the model is loaded with its environments"
        replay_buffer.set_env(model.env)
        replay_buffer.truncate_last_trajectory()
    replay_buffer.device = model.device


def _saved_with(model_path: str, env_id: str) -> tuple[str | None, str | None]:
    """
    A model's replay buffer and ``VecNormalize`` statistics (``None`` where absent): a checkpoint's own, else the RL
    Zoo's ``replay_buffer.pkl`` beside the model and ``{env_name}/vecnormalize.pkl``.
    """
    layout = RunLayout(os.path.dirname(os.path.abspath(model_path)), env_id)
    files = (os.path.join(layout.run_dir, "replay_buffer.pkl"), layout.vecnormalize)
    for checkpoint in layout.checkpoints():
        if os.path.abspath(checkpoint.model) == os.path.abspath(model_path):
            files = (checkpoint.replay_buffer, checkpoint.vecnormalize)
    replay_buffer, statistics = (path if os.path.isfile(path) else None for path in files)
    return replay_buffer, statistics


def load_trained_agent(
    algorithm_class: type[Any], path: str, env_id: str, trust: bool = False, **kwargs: Any
) -> BaseAlgorithm:
    """
    A saved model to continue (the RL Zoo's ``-i``) with the replay buffer saved with it, its timestep count at 0.
    Neither file runs code unless ``trust``.

    :param algorithm_class: The run's algorithm
    :param path: The model file
    :param env_id: The environment id of its run
    :param trust: Unpickle the files as SB3 does
    :param kwargs: Keyword arguments of its ``load``
    :raises ValueError: for a replay buffer beside a model that has none
    """
    with model_file_errors(path, algorithm_class.__name__), loading_model():
        model = algorithm_class.load(path, custom_objects=load_objects(path, trust), **kwargs)
    replay_buffer, _ = _saved_with(path, env_id)
    if replay_buffer is not None:
        if not hasattr(model, "load_replay_buffer"):
            raise ValueError(f"{type(model).__name__} has no replay buffer to load {replay_buffer} into")
        zoo = os.path.basename(replay_buffer) == "replay_buffer.pkl"
        print(f"{'Loading replay buffer' if zoo else 'Loading the replay buffer'} {replay_buffer}")
        if trust:
            model.load_replay_buffer(replay_buffer)
        else:
            try:
                loaded = restricted_load(replay_buffer, REPLAY_BUFFER_GLOBALS, "a replay buffer")
            except UnsafeModelFileError:
                raise
            except Exception as error:  # unpickling a damaged file can raise almost anything
                problem = f"{type(error).__name__}: {error}"
                raise model_file_error(f"{replay_buffer} is not a readable replay buffer: {problem}") from error
            if not isinstance(loaded, ReplayBuffer):
                raise model_file_error(f"{replay_buffer} holds a {type(loaded).__name__}, not a replay buffer")
            _use_replay_buffer(model, loaded)
    model.num_timesteps = 0
    return model


def saved_statistics(model_path: str, env_id: str, trust: bool = False) -> str | VecNormalize | None:
    """
    The ``VecNormalize`` statistics saved with a model to continue: the file (read later by the restricted unpickler)
    or, when trusted, the statistics unpickled (``None``: none).

    :param model_path: The model file (``""``: none, no statistics)
    :param env_id: The environment id of its run
    :param trust: Unpickle the file as SB3 does
    :raises UnsafeModelFileError: for a trusted file that holds no statistics
    """
    statistics = _saved_with(model_path, env_id)[1] if model_path else None
    if statistics is not None and trust:
        loaded = load_from_pkl(statistics)
        if not isinstance(loaded, VecNormalize):
            raise UnsafeModelFileError(f"{statistics} holds a {type(loaded).__name__}, not VecNormalize statistics")
        return loaded
    return statistics


def restore_records(layout: RunLayout, checkpoint: Checkpoint | None, n_envs: int) -> None:
    """
    Keep a run's evaluations and episodes up to its checkpoint; from scratch (``checkpoint`` ``None``), remove them.

    :param layout: The run's paths
    :param checkpoint: The checkpoint it resumes from
    :param n_envs: Its training environments (each monitor file holds its share of the timesteps)
    """
    if checkpoint is None:
        remove_files([layout.evaluations, layout.best_model, *layout.monitor_files()])
        return
    start = checkpoint.timesteps
    try:
        history = EvaluationHistory.load(layout.evaluations)
    except DamagedFileError as error:
        print(f"{error}; the evaluations before timestep {start} are lost and the history restarts after it.")
        history = EvaluationHistory()
    history.until(start).save(layout.evaluations)
    for path in layout.monitor_files():
        truncate_monitor(path, start // n_envs)
