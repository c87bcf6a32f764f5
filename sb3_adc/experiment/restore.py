"""
Restoring a run from its files without running code from them: a checkpoint of its own (:func:`read_checkpoint`),
or a saved model to continue (the RL Zoo's ``-i``, :func:`load_trained_agent`) with the replay buffer and
``VecNormalize`` statistics saved with it; and the run's records cut back to its checkpoint (:func:`restore_records`).
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
from sb3_adc.experiment.continuation import Continuation
from sb3_adc.experiment.layout import Checkpoint, DamagedFileError, RunLayout
from sb3_adc.experiment.manifest import manifest_damage
from sb3_adc.experiment.monitor_files import truncate_monitor


class DamagedCheckpoint(ValueError):
    """A checkpoint that cannot be resumed from: a file is missing, truncated or corrupted (the message says which)."""


@dataclass
class CheckpointContents:
    """
    A checkpoint read by :func:`read_checkpoint`: what a resume loads, each file read once.

    :param checkpoint: Its files
    :param model_objects: The ``custom_objects`` that load its model zip without unpickling anything
        (:func:`~sb3_adc.common.safe_load.safe_objects`); ``None`` when trusted (SB3 unpickles the zip)
    :param replay_buffer: Its replay buffer (``None`` where it has none)
    :param vecnormalize: Its ``VecNormalize`` statistics, without environments (``None`` where it has none)
    :param continuation: Its continuation (``None`` where it has none, or one of another version)
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
        :param kwargs: Keyword arguments of its ``load`` (``env``, ``device``, ...)
        """
        with loading_model():
            model = algorithm_class.load(self.checkpoint.model, custom_objects=self.model_objects, **kwargs)
        if self.replay_buffer is not None and hasattr(model, "load_replay_buffer"):
            _use_replay_buffer(model, self.replay_buffer)
        return model


def read_checkpoint(checkpoint: Checkpoint, trust: bool = False) -> CheckpointContents:
    """
    Read a checkpoint to resume from, and tell whether it can be: its files must be those its manifest lists
    (:func:`~sb3_adc.experiment.manifest.manifest_damage`, checked before anything is unpickled; a checkpoint written
    before manifests, or cut before its manifest, has none); its model zip must open with intact members (CRC
    checked) and an SB3 model's ``data``; its replay buffer, ``VecNormalize`` statistics and continuation, where
    present, must unpickle. Nothing of the files runs code: the model's entries are built from the safe load's
    allow-list (:func:`~sb3_adc.common.safe_load.safe_objects`), each pickle from the allow-list of what sb3-adc
    writes in such a file (:data:`~sb3_adc.common.safe_load.REPLAY_BUFFER_GLOBALS`,
    :data:`~sb3_adc.common.safe_load.VEC_NORMALIZE_GLOBALS`,
    :data:`~sb3_adc.common.safe_load.CONTINUATION_GLOBALS`).

    :param checkpoint: The checkpoint
    :param trust: Unpickle its files as SB3 does, which can run any code they hold (a run folder one trusts that
        holds objects outside the allow-lists, e.g. a custom environment's in its infos)
    :raises DamagedCheckpoint: for a missing model zip or a damaged file, naming it
    :raises UnsafeModelFileError: for a file that needs a class or function outside its allow-list (a file planted
        in the run folder, or written by other code): refused, not run, and not taken for damage
    """
    name = os.path.basename(checkpoint.model)
    if not os.path.isfile(checkpoint.model):
        raise DamagedCheckpoint(f"{name} is missing")
    damage = manifest_damage(checkpoint) if os.path.isfile(checkpoint.manifest) else None
    if damage is not None:
        raise DamagedCheckpoint(damage)
    try:
        with zipfile.ZipFile(checkpoint.model) as archive:
            broken = archive.testzip()
            names = archive.namelist()
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
    globals_of = {
        checkpoint.replay_buffer: (REPLAY_BUFFER_GLOBALS, "a replay buffer"),
        checkpoint.vecnormalize: (VEC_NORMALIZE_GLOBALS, "VecNormalize statistics"),
        checkpoint.continuation: (CONTINUATION_GLOBALS, "a continuation"),
    }
    loaded: dict[str, Any] = {}
    for path, (allowed, what) in globals_of.items():
        if not os.path.isfile(path):
            continue
        try:
            loaded[path] = load_from_pkl(path) if trust else restricted_load(path, allowed, what)
        except UnsafeModelFileError:
            raise
        except Exception as error:  # unpickling a damaged file can raise almost anything
            raise DamagedCheckpoint(f"{os.path.basename(path)} does not unpickle ({type(error).__name__}: {error})") from None
    contents.replay_buffer = loaded.get(checkpoint.replay_buffer)
    if contents.replay_buffer is not None and not isinstance(contents.replay_buffer, ReplayBuffer):
        raise DamagedCheckpoint(f"{os.path.basename(checkpoint.replay_buffer)} holds no replay buffer")
    statistics = loaded.get(checkpoint.vecnormalize)
    if statistics is not None and not isinstance(statistics, VecNormalize):
        raise DamagedCheckpoint(f"{os.path.basename(checkpoint.vecnormalize)} holds no VecNormalize statistics")
    contents.vecnormalize = statistics
    if checkpoint.continuation in loaded:
        contents.continuation = Continuation.accept(loaded[checkpoint.continuation])
    return contents


def checkpoint_damage(checkpoint: Checkpoint, trust: bool = False) -> str | None:
    """
    Why a checkpoint cannot be resumed from, or ``None`` if it can: its manifest's check, which unpickles nothing
    (:func:`~sb3_adc.experiment.manifest.manifest_damage`), or, for a checkpoint without one,
    :func:`read_checkpoint`, whose content is dropped (a resume keeps it instead).

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


def _use_replay_buffer(model: OffPolicyAlgorithm, replay_buffer: object) -> None:
    """
    What SB3's ``load_replay_buffer`` (``truncate_last_traj=True``) does with the buffer it unpickled, for one read
    already (by a restricted unpickler, or by a checkpoint's check): the model takes it, on the model's device.

    :param model: The model
    :param replay_buffer: The unpickled buffer
    :raises ValueError: if it is not a replay buffer
    """
    if not isinstance(replay_buffer, ReplayBuffer):
        raise ValueError(f"not a replay buffer: a {type(replay_buffer).__name__}")
    model.replay_buffer = replay_buffer
    if not hasattr(replay_buffer, "handle_timeout_termination"):  # SB3 < 2.1's buffers, as SB3 reads them
        replay_buffer.handle_timeout_termination = False
        replay_buffer.timeouts = np.zeros_like(replay_buffer.dones)
    if isinstance(replay_buffer, HerReplayBuffer):  # only from a trusted file: not in the restricted allow-list
        assert model.env is not None, "the model is loaded with its environments"
        replay_buffer.set_env(model.env)
        replay_buffer.truncate_last_trajectory()
    replay_buffer.device = model.device


def _read_replay_buffer(path: str) -> ReplayBuffer:
    """
    A replay buffer saved with a model to continue, read with the restricted unpickler.

    :param path: The pickle
    :raises UnsafeModelFileError: for a file that needs more than a replay buffer holds
    :raises ModelFileError: for a damaged file, naming it
    """
    try:
        replay_buffer = restricted_load(path, REPLAY_BUFFER_GLOBALS, "a replay buffer")
    except UnsafeModelFileError:
        raise
    except Exception as error:  # unpickling a damaged file can raise almost anything
        raise model_file_error(f"{path} is not a readable replay buffer: {type(error).__name__}: {error}") from error
    if not isinstance(replay_buffer, ReplayBuffer):
        raise model_file_error(f"{path} holds a {type(replay_buffer).__name__}, not a replay buffer")
    return replay_buffer


def saved_with(model_path: str, env_id: str) -> tuple[str | None, str | None]:
    """
    The replay buffer and ``VecNormalize`` statistics saved with a model (``None`` where absent): a checkpoint's
    own (``rl_model_{t}_steps.zip``), else the RL Zoo's ``replay_buffer.pkl`` beside the model and
    ``{env_name}/vecnormalize.pkl``.

    :param model_path: The model file
    :param env_id: The environment id of its run
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
    A saved model to continue (the RL Zoo's ``-i``) with the replay buffer saved with it (:func:`saved_with`), its
    timestep count at 0. Neither file runs code unless ``trust``.

    :param algorithm_class: The run's algorithm
    :param path: The model file
    :param env_id: The environment id of its run
    :param trust: Unpickle the files as SB3 does
    :param kwargs: Keyword arguments of its ``load`` (``env``, ``device``, the run's hyperparameters, ...)
    :raises ValueError: for a replay buffer beside a model that has none
    """
    with model_file_errors(path, algorithm_class.__name__), loading_model():
        model = algorithm_class.load(path, custom_objects=load_objects(path, trust), **kwargs)
    replay_buffer, _ = saved_with(path, env_id)
    if replay_buffer is not None:
        if not hasattr(model, "load_replay_buffer"):
            raise ValueError(f"{type(model).__name__} has no replay buffer to load {replay_buffer} into")
        zoo = os.path.basename(replay_buffer) == "replay_buffer.pkl"
        print(f"{'Loading replay buffer' if zoo else 'Loading the replay buffer'} {replay_buffer}")
        if trust:
            model.load_replay_buffer(replay_buffer)
        else:
            _use_replay_buffer(model, _read_replay_buffer(replay_buffer))
    model.num_timesteps = 0
    return model


def saved_statistics(model_path: str, env_id: str, trust: bool = False) -> str | VecNormalize | None:
    """
    The ``VecNormalize`` statistics saved with a model to continue (:func:`saved_with`): the file, which the
    restricted unpickler reads, or, when trusted, the statistics unpickled (``None``: none).

    :param model_path: The model file (``""``: none, no statistics)
    :param env_id: The environment id of its run
    :param trust: Unpickle the file as SB3 does
    :raises UnsafeModelFileError: for a trusted file that holds no statistics
    """
    statistics = saved_with(model_path, env_id)[1] if model_path else None
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
        for path in [layout.evaluations, layout.best_model, *layout.monitor_files()]:
            if os.path.exists(path):
                os.remove(path)
        return
    start = checkpoint.timesteps
    try:
        history = EvaluationHistory.load(layout.evaluations)
    except DamagedFileError as error:
        # The evaluations up to the checkpoint cannot be recovered; the run goes on without them.
        print(f"{error}; the evaluations before timestep {start} are lost and the history restarts after it.")
        history = EvaluationHistory()
    history.until(start).save(layout.evaluations)
    for path in layout.monitor_files():
        truncate_monitor(path, start // n_envs)
