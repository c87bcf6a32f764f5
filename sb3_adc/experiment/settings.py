"""The settings of a training run (what ``sb3-adc train`` is asked to do), saved as the run's ``args.yml``."""

from __future__ import annotations

import dataclasses
import importlib.util
import inspect
import os
from dataclasses import dataclass, field
from typing import Any

import yaml

from sb3_adc.common.atomic import write_atomically
from sb3_adc.config.loader import read_yaml_file
from sb3_adc.experiment.layout import env_name

#: Evaluations per run when ``eval_freq`` is not given.
DEFAULT_EVALUATIONS_PER_RUN = 20
#: Seed offset of the evaluation environments (they never replay the training environments' episodes).
EVAL_SEED_OFFSET = 10_000
#: ``best_model_metric`` choices: what picks ``best_model.zip`` among the periodic evaluations.
BEST_MODEL_METRICS = ("return", "success")
#: Folder of the TensorBoard logs of tracked runs (``--track`` without ``-tb``), under the log folder.
TRACKED_TENSORBOARD_FOLDER = "tensorboard"
#: Keyword arguments of ``gym.make`` itself, accepted for every environment.
GYM_MAKE_KEYWORDS = ("max_episode_steps", "disable_env_checker")


def write_yaml(path: str, data: Any) -> None:
    """
    Write ``data`` as YAML (``yaml.safe_dump``, sorted keys), atomically.

    :param path: The file
    :param data: What to write
    """
    text = yaml.safe_dump(data, sort_keys=True)
    write_atomically(path, lambda stream: stream.write(text))


class SettingsError(ValueError):
    """
    An invalid run setting (exit status 2, before anything is written), named with its option and accepted values.

    :param name: The setting (a field of :class:`TrainSettings`)
    :param problem: What is wrong and what is accepted
    :param option: The command-line option (default: ``--`` and the name with dashes)
    """

    def __init__(self, name: str, problem: str, option: str | None = None):
        self.name = name
        self.option = option or "--" + name.replace("_", "-")
        super().__init__(f"`{name}` {problem} (command-line option {self.option})")


def check_device(device: str) -> None:
    """
    Check a PyTorch device name: ``auto`` (SB3's choice) or one ``torch.device`` accepts.

    :param device: The name
    :raises SettingsError: if it is neither
    """
    import torch as th

    if device != "auto":
        try:
            th.device(device)
        except (RuntimeError, TypeError):
            problem = f"must be auto, cpu, cuda, cuda:N or another PyTorch device type (mps, xpu, ...), got {device!r}"
            raise SettingsError("device", problem) from None


def check_env_kwargs(env_id: str, env_kwargs: dict[str, Any], name: str = "env_kwargs") -> None:
    """
    Make the environment once with ``env_kwargs``: a keyword or value it rejects is a :class:`SettingsError`.

    :param env_id: The environment id (registered)
    :param env_kwargs: Keyword arguments of ``gym.make``
    :param name: The setting that gave them (``env_kwargs``, ``eval_env_kwargs``), for the message
    :raises SettingsError: if ``gym.make`` raises a ``TypeError`` or ``ValueError``
    """
    import gymnasium as gym
    from gymnasium.envs.registration import load_env_creator

    try:
        gym.make(env_id, **env_kwargs).close()
    except (TypeError, ValueError) as error:
        spec, keywords = gym.spec(env_id), list(GYM_MAKE_KEYWORDS)  # the entry point's keywords, then gym.make's
        try:
            creator = spec.entry_point if callable(spec.entry_point) else load_env_creator(str(spec.entry_point))
            parameters = inspect.signature(creator).parameters.values()
            kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
            keywords[:0] = [item.name for item in parameters if item.kind in kinds and item.name != "self"]
        except (ValueError, TypeError, ImportError, AttributeError):  # no signature to read: gym.make's own only
            pass
        problem = f"rejected by {env_id}: {error}. Keywords it accepts: {', '.join(keywords)}"
        raise SettingsError(name, problem) from None


@dataclass
class TrainSettings:
    """
    What to train and how to log it.

    :param algo: The algorithm's name (``adc``, ``ddpg``, ``td3``, ``sac``, ``dqn``, ``vanilla_ac``)
    :param env_id: The environment id
    :param seed: Seed of the model, the environments and the noise
    :param conf_file: Hyperparameter file, or the name of a shipped one; ``None`` uses the shipped ``{algo}.yml``
    :param overrides: ``key: value`` replacing the entry's values (``-params``)
    :param env_kwargs: Keyword arguments of ``gym.make`` replacing the entry's ``env_kwargs`` keys
    :param n_timesteps: Training budget replacing the entry's ``n_timesteps``
    :param log_folder: Root of the RL-Zoo log layout
    :param run_dir: Explicit run folder (instead of ``{log_folder}/{algo}/{env}_{next id}``)
    :param eval_freq: Evaluate every this many timesteps (``None``: 20 evaluations per run; ``<= 0``: never)
    :param eval_episodes: Deterministic episodes per periodic evaluation
    :param n_eval_envs: Environments of the periodic evaluations
    :param save_freq: Checkpoint every this many timesteps (``None``: at every evaluation; ``<= 0``: never)
    :param keep_checkpoints: How many of the latest checkpoints to keep
    :param final_eval_episodes: Deterministic episodes of the final evaluation
    :param vec_env: ``dummy`` (one process) or ``subproc`` (one process per training environment)
    :param device: PyTorch device (``auto``, ``cpu``, ``cuda``)
    :param verbose: SB3 verbosity (0: quiet, 1: training logs)
    :param progress_bar: Whether to show a progress bar
    :param eval_env_kwargs: Keyword arguments replacing ``env_kwargs``' in the evaluation environments only
    :param tensorboard_log: TensorBoard log folder (the RL Zoo's ``-tb``; ``None``: none, or
        ``{log_folder}/tensorboard`` when tracking)
    :param trained_agent: A saved model to train ``n_timesteps`` more, with its replay buffer (the RL Zoo's ``-i``)
    :param track: Track the run with Weights & Biases (the ``track`` extra), which uploads the TensorBoard logs
    :param wandb_project_name: The Weights & Biases project of a tracked run
    :param wandb_entity: The Weights & Biases entity (team) of a tracked run (``None``: the user's default)
    :param best_model_metric: What picks ``best_model.zip``: ``return`` (the highest mean return) or ``success`` (the
        highest success rate, ties broken by the return; the episodes must report ``info["is_success"]``)
    """

    algo: str
    env_id: str
    seed: int = 0
    conf_file: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    n_timesteps: int | None = None
    log_folder: str = "logs"
    run_dir: str | None = None
    eval_freq: int | None = None
    eval_episodes: int = 5
    n_eval_envs: int = 1
    save_freq: int | None = None
    keep_checkpoints: int = 2
    final_eval_episodes: int = 10
    vec_env: str = "dummy"
    device: str = "auto"
    verbose: int = 0
    progress_bar: bool = True
    # Added after the first release: args.yml files without them load with these defaults.
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    tensorboard_log: str | None = None
    trained_agent: str | None = None
    track: bool = False
    wandb_project_name: str = "sb3-adc"
    wandb_entity: str | None = None
    best_model_metric: str = "return"

    def __post_init__(self) -> None:
        """Check the settings (:class:`SettingsError`), and resolve the TensorBoard folder of a tracked run."""
        for name in ("eval_episodes", "n_eval_envs", "keep_checkpoints", "final_eval_episodes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise SettingsError(name, f"must be an integer >= 1, got {value!r}")
        if self.vec_env not in ("dummy", "subproc"):
            raise SettingsError("vec_env", f"must be 'dummy' or 'subproc', got {self.vec_env!r}")
        if self.best_model_metric not in BEST_MODEL_METRICS:
            metrics = ", ".join(BEST_MODEL_METRICS)
            raise SettingsError("best_model_metric", f"must be one of {metrics}, got {self.best_model_metric!r}")
        if not isinstance(self.device, str):
            raise SettingsError("device", f"must be a string, got {self.device!r}")
        check_device(self.device)
        for name in ("overrides", "env_kwargs", "eval_env_kwargs"):
            value = getattr(self, name)
            if not isinstance(value, dict) or not all(isinstance(key, str) for key in value):
                raise SettingsError(name, f"must be a mapping of names to values, got {value!r}")
        for name in ("tensorboard_log", "trained_agent", "wandb_entity"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, str) or not value):
                raise SettingsError(name, f"must be a non-empty string or None, got {value!r}")
        if not isinstance(self.wandb_project_name, str) or not self.wandb_project_name:
            raise SettingsError("wandb_project_name", f"must be a non-empty string, got {self.wandb_project_name!r}")
        if self.track and self.tensorboard_log is None:  # Weights & Biases uploads the TensorBoard logs
            self.tensorboard_log = os.path.join(self.log_folder, TRACKED_TENSORBOARD_FOLDER)
        if self.tensorboard_log is not None and importlib.util.find_spec("tensorboard") is None:
            problem = "needs the tensorboard package, which is not installed: pip install tensorboard"
            raise SettingsError("tensorboard_log", problem)

    def tensorboard_folder(self) -> str | None:
        """The model's ``tensorboard_log``: ``{tensorboard_log}/{env_name}``, as the RL Zoo's (``None``: no logs)."""
        return None if self.tensorboard_log is None else os.path.join(self.tensorboard_log, env_name(self.env_id))

    def evaluation_env_kwargs(self, env_kwargs: dict[str, Any]) -> dict[str, Any]:
        """
        The evaluation environments' keyword arguments: ``env_kwargs`` updated with :attr:`eval_env_kwargs`.

        :param env_kwargs: Those of the training environments
        """
        return {**env_kwargs, **self.eval_env_kwargs}

    def check_env_kwargs(self, env_id: str, env_kwargs: dict[str, Any]) -> None:
        """
        :func:`check_env_kwargs` for the training and the evaluation keyword arguments.

        :param env_id: The environment id
        :param env_kwargs: The training environments' keyword arguments
        :raises SettingsError: if the environment rejects them
        """
        check_env_kwargs(env_id, env_kwargs, "env_kwargs")
        if self.eval_env_kwargs:
            check_env_kwargs(env_id, self.evaluation_env_kwargs(env_kwargs), "eval_env_kwargs")

    def evaluation_interval(self, n_timesteps: int) -> int:
        """
        Timesteps between periodic evaluations (0: none).

        :param n_timesteps: The run's budget
        """
        if self.eval_freq is None:
            return max(n_timesteps // DEFAULT_EVALUATIONS_PER_RUN, 1)
        return max(self.eval_freq, 0)

    def checkpoint_interval(self, n_timesteps: int) -> int:
        """
        Timesteps between checkpoints (0: none).

        :param n_timesteps: The run's budget
        """
        if self.save_freq is None:
            return self.evaluation_interval(n_timesteps) or max(n_timesteps // DEFAULT_EVALUATIONS_PER_RUN, 1)
        return max(self.save_freq, 0)

    def save(self, path: str) -> None:
        """
        Write the settings as YAML, atomically.

        :param path: The file
        """
        write_yaml(path, dataclasses.asdict(self))

    @classmethod
    def load(cls, path: str) -> TrainSettings:
        """
        Read settings written by :meth:`save` (of this version or an earlier one).

        :param path: The file
        :raises ValueError: if the file does not hold settings (``HyperparamsError``: not YAML, or over a limit;
            :class:`SettingsError`: an invalid value)
        """
        data = read_yaml_file(path)
        names = {item.name for item in dataclasses.fields(cls)}
        if not isinstance(data, dict) or not {"algo", "env_id"} <= set(data) or not set(data) <= names:
            raise ValueError(f"{path} does not hold sb3-adc run settings (expected the keys {', '.join(sorted(names))}).")
        return cls(**data)

    @classmethod
    def of_run(cls, run_dir: str) -> TrainSettings:
        """
        The settings of a run, from its ``{run_dir}/{env_name}/args.yml``.

        :param run_dir: The run's folder
        :raises FileNotFoundError: if the folder holds no run
        :raises ValueError: if its ``args.yml`` does not hold settings (see :meth:`load`)
        """
        for name in sorted(os.listdir(run_dir)) if os.path.isdir(run_dir) else []:
            path = os.path.join(run_dir, name, "args.yml")
            if os.path.isfile(path):
                return cls.load(path)
        raise FileNotFoundError(f"{run_dir} holds no sb3-adc run (no */args.yml); start one with sb3-adc train.")
