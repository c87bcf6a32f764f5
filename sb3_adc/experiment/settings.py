"""The settings of a training run (what ``sb3-adc train`` is asked to do), saved as the run's ``args.yml``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import yaml

#: Evaluations per run when ``eval_freq`` is not given.
DEFAULT_EVALUATIONS_PER_RUN = 20
#: Seed offset of the evaluation environments (they never replay the training environments' episodes).
EVAL_SEED_OFFSET = 10_000


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
    :param keep_checkpoints: How many of the latest checkpoints to keep (older ones are deleted)
    :param final_eval_episodes: Deterministic episodes of the final evaluation
    :param vec_env: ``dummy`` (one process) or ``subproc`` (one process per training environment)
    :param device: PyTorch device (``auto``, ``cpu``, ``cuda``)
    :param verbose: SB3 verbosity (0: quiet, 1: training logs)
    :param progress_bar: Whether to show a progress bar
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

    def __post_init__(self) -> None:
        for name in ("eval_episodes", "n_eval_envs", "keep_checkpoints", "final_eval_episodes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"`{name}` must be an integer >= 1, got {value!r}.")
        if self.vec_env not in ("dummy", "subproc"):
            raise ValueError(f"`vec_env` must be 'dummy' or 'subproc', got {self.vec_env!r}.")

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
        Write the settings as YAML.

        :param path: The file
        """
        with open(path, "w", encoding="utf-8") as stream:
            yaml.safe_dump(dataclasses.asdict(self), stream, sort_keys=True)

    @classmethod
    def load(cls, path: str) -> TrainSettings:
        """
        Read settings written by :meth:`save`.

        :param path: The file
        :raises ValueError: if the file does not hold settings
        """
        with open(path, encoding="utf-8") as stream:
            data = yaml.safe_load(stream)
        names = {item.name for item in dataclasses.fields(cls)}
        if not isinstance(data, dict) or not {"algo", "env_id"} <= set(data) or not set(data) <= names:
            raise ValueError(f"{path} does not hold sb3-adc run settings (expected the keys {', '.join(sorted(names))}).")
        return cls(**data)
