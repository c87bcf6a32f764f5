"""Running a trained model: episodes, returns, and an optional GIF or video of a rollout."""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

from sb3_adc.common.model_files import loading_model
from sb3_adc.common.safe_load import UnsafeModelFileError, safe_objects
from sb3_adc.config import ExperimentConfig, resolve_entry
from sb3_adc.config.loader import read_yaml_file
from sb3_adc.experiment.envs import make_run_envs, wrap_vec_env
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.settings import TrainSettings

#: Which model of a run to load: the final model, the best one, or the latest checkpoint.
MODEL_CHOICES = ("final", "best", "last-checkpoint")


@dataclass
class Rollouts:
    """
    Returns of the episodes played, and the frames of the recorded one.

    :param returns: Return of each episode
    :param lengths: Length of each episode
    :param frames: RGB frames of the first episode (when recording)
    """

    returns: list[float] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)
    frames: list[np.ndarray] = field(default_factory=list)


def load_run(run_dir: str) -> tuple[TrainSettings, ExperimentConfig, RunLayout]:
    """
    The settings, hyperparameters and paths of a run.

    :param run_dir: The run's folder
    :raises FileNotFoundError: if the folder holds no run
    :raises HyperparamsError: if its ``config.yml`` or ``args.yml`` does not read or holds invalid values
    """
    settings = TrainSettings.of_run(run_dir)
    layout = RunLayout(run_dir, settings.env_id)
    config = resolve_entry(settings.algo, settings.env_id, read_yaml_file(layout.config), layout.config)
    return settings, config, layout


def model_path(layout: RunLayout, which: str) -> tuple[str, str | None]:
    """
    The model file of a run and the ``VecNormalize`` statistics that go with it.

    :param layout: The run's paths
    :param which: ``final``, ``best`` or ``last-checkpoint``
    :raises FileNotFoundError: if that model does not exist (yet)
    """
    if which not in MODEL_CHOICES:
        raise ValueError(f"`which` must be one of {', '.join(MODEL_CHOICES)}, got {which!r}.")
    statistics: str | None = layout.vecnormalize
    if which != "last-checkpoint":
        path = layout.final_model if which == "final" else layout.best_model
    else:
        checkpoints = layout.checkpoints()
        if not checkpoints:
            raise FileNotFoundError(f"{layout.run_dir} has no checkpoint.")
        path, statistics = checkpoints[-1].model, checkpoints[-1].vecnormalize
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path} does not exist (has the run finished? try --model best or last-checkpoint).")
    return path, statistics if statistics is not None and os.path.isfile(statistics) else None


def load_model(config: ExperimentConfig, path: str, device: str = "auto", safe: bool = True) -> BaseAlgorithm:
    """
    Load a model for prediction only.

    :param config: The run's hyperparameters (for the algorithm class)
    :param path: The model zip
    :param device: PyTorch device
    :param safe: Run no code from the file (:func:`~sb3_adc.common.safe_load.safe_objects`); ``False``: as SB3 does
    :raises UnsafeModelFileError: if ``safe`` and the file needs a class outside the safe load's allow-list
    """
    kwargs: dict[str, Any] = {"buffer_size": 1} if issubclass(config.algorithm_class, OffPolicyAlgorithm) else {}
    custom_objects = None
    if safe:
        try:
            custom_objects = safe_objects(path)
        except UnsafeModelFileError:
            raise
        except (OSError, zipfile.BadZipFile, KeyError, ValueError):
            custom_objects = None  # damaged: the load below fails on it, unpickling nothing, naming the file
    with loading_model():
        return config.algorithm_class.load(path, device=device, custom_objects=custom_objects, **kwargs)


def play(
    model: BaseAlgorithm,
    config: ExperimentConfig,
    n_episodes: int,
    seed: int,
    statistics: str | None = None,
    deterministic: bool = True,
    record: bool = False,
) -> Rollouts:
    """
    Play ``n_episodes`` episodes of ``model`` in the run's environment (wrappers and statistics applied).

    :param model: The model
    :param config: The run's hyperparameters
    :param n_episodes: Number of episodes (>= 1)
    :param seed: Seed of the environment
    :param statistics: Saved ``VecNormalize`` statistics (required when the run normalizes observations)
    :param deterministic: Deterministic actions
    :param record: Keep the RGB frames of the first episode
    """
    if n_episodes < 1:
        raise ValueError(f"`n_episodes` must be >= 1, got {n_episodes}.")
    if config.normalize is not None and statistics is None:
        raise FileNotFoundError("this run normalizes observations but its VecNormalize statistics were not found.")
    venv = make_run_envs(config, 1, seed, render_mode="rgb_array" if record else None)
    venv = wrap_vec_env(config, venv, training=False, statistics=statistics)
    rollouts = Rollouts()
    observation = venv.reset()
    try:
        while len(rollouts.returns) < n_episodes:
            if record and not rollouts.returns:
                frame = venv.render()
                if frame is not None:
                    rollouts.frames.append(np.asarray(frame))
            action, _ = model.predict(observation, deterministic=deterministic)  # type: ignore[arg-type]
            observation, _, done, infos = venv.step(action)
            if done[0]:  # the Monitor's record: the return before any normalization
                rollouts.returns.append(float(infos[0]["episode"]["r"]))
                rollouts.lengths.append(int(infos[0]["episode"]["l"]))
    finally:
        venv.close()
    return rollouts


def write_recording(frames: list[np.ndarray], path: str, fps: int) -> None:
    """
    Write frames as a GIF (``.gif``) or a video (``.mp4``, ``.webm``, ...; needs ``imageio-ffmpeg``).

    :param frames: RGB frames
    :param path: The output file
    :param fps: Frames per second
    """
    import imageio

    if not frames:
        raise ValueError("no frames to write: the environment returned no image (does it support render_mode='rgb_array'?)")
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    if path.lower().endswith(".gif"):
        imageio.v3.imwrite(path, np.stack(frames), extension=".gif", duration=1000.0 / fps, loop=0)
        return
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise ImportError(
            f"writing the video {path} needs imageio-ffmpeg: pip install imageio-ffmpeg (or use a .gif)"
        ) from None
    writer: Any = imageio.v2.get_writer(path, fps=fps, macro_block_size=1)
    with writer:
        for frame in frames:
            writer.append_data(frame)
