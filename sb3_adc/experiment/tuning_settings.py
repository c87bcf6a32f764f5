"""What a study tunes and how (:class:`TuneSettings`), and the checks of its settings made before anything is written."""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym

from sb3_adc.config import HyperparamsError, load_hyperparams
from sb3_adc.experiment.evaluation import success_unreported
from sb3_adc.experiment.layout import env_name
from sb3_adc.experiment.samplers import SAMPLERS

#: ``--sampler``, ``--pruner`` and ``--objective`` choices (a trial's value: the final evaluations' mean of what).
SAMPLER_NAMES = ("tpe", "random")
PRUNER_NAMES = ("median", "halving", "none")
OBJECTIVE_NAMES = ("return", "success")
#: Bounds of a search space (``--search-space``): keys, and choices per key.
MAX_SEARCH_KEYS = MAX_CHOICES = 32
#: Workers (``--n-jobs``) per CPU at most: a worker trains on one thread in its own process (a few hundred MB).
MAX_JOBS_PER_CPU = 2
#: A refused command-line option: ``refused(option, reason)``.
refused = functools.partial(HyperparamsError, "command line")


@dataclass
class TuneSettings:
    """
    What to tune and how.

    :param algo: The algorithm's name (one of :data:`~sb3_adc.experiment.samplers.SAMPLERS`)
    :param env_id: The environment id
    :param n_trials: Finished trials (complete or pruned) the study holds at the end, the shipped entry included
    :param n_timesteps: Training budget of each run (``None``: the entry's)
    :param seeds: Seeds each trial trains on (tune on seeds that the final comparison does not use)
    :param sampler: ``tpe`` (Optuna's default) or ``random``
    :param pruner: ``median``, ``halving`` (successive halving) or ``none``
    :param n_startup_trials: Trials sampled at random before TPE takes over and the median pruner prunes
    :param n_evaluations: Evaluations per run reported to the pruner
    :param eval_episodes: Deterministic episodes of each of those evaluations
    :param final_eval_episodes: Deterministic episodes of each run's final evaluation (the trial's value)
    :param objective: ``return`` (mean return, the RL Zoo's) or ``success`` (success rate) of the evaluations
    :param n_jobs: Worker processes
    :param storage: A database URL (``sqlite:///study.db``, needs SQLAlchemy) or a journal file (``*.log``);
        ``None``: ``study.log`` in the study folder
    :param study_name: The study's name (``None``: ``{algo}-{env}``)
    :param sampler_seed: Seed of the sampler (worker ``k`` uses ``sampler_seed + k``)
    :param conf_file: Hyperparameter file whose entry is the starting point (``None``: the shipped ``{algo}.yml``)
    :param overrides: Values fixed in every trial (``-params``), outside the search
    :param env_kwargs: Keyword arguments of ``gym.make``
    :param eval_env_kwargs: Keyword arguments of ``gym.make`` replacing those of ``env_kwargs`` in the evaluations
    :param search_space: Choices per key, drawn in every trial (see :class:`~sb3_adc.experiment.samplers.Space`)
    :param log_folder: Root of the log layout
    :param device: PyTorch device
    :param verbose: SB3 verbosity of the runs
    """

    algo: str
    env_id: str
    n_trials: int = 10
    n_timesteps: int | None = None
    seeds: tuple[int, ...] = (0,)
    sampler: str = "tpe"
    pruner: str = "median"
    n_startup_trials: int = 5
    n_evaluations: int = 5
    eval_episodes: int = 5
    final_eval_episodes: int = 10
    objective: str = "return"
    n_jobs: int = 1
    storage: str | None = None
    study_name: str | None = None
    sampler_seed: int = 0
    conf_file: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    search_space: dict[str, list[Any]] = field(default_factory=dict)
    log_folder: str = "logs"
    device: str = "auto"
    verbose: int = 0

    def __post_init__(self) -> None:
        if self.algo not in SAMPLERS:
            raise refused("--algo", f"no search space for {self.algo!r}; tunable: {', '.join(SAMPLERS)}")
        for option, name, accepted in (
            ("--sampler", self.sampler, SAMPLER_NAMES),
            ("--pruner", self.pruner, PRUNER_NAMES),
            ("--objective", self.objective, OBJECTIVE_NAMES),
        ):
            if name not in accepted:
                raise refused(option, f"{name!r}; accepted: {', '.join(accepted)}")
        # The shape of the search space here; its values are checked by `check_search_space`.
        space = self.search_space
        if not isinstance(space, dict) or not all(isinstance(key, str) for key in space):
            raise refused("--search-space", f"must map hyperparameter names to lists of choices, got {space!r}")
        if len(space) > MAX_SEARCH_KEYS:
            raise refused("--search-space", f"at most {MAX_SEARCH_KEYS} keys, got {len(space)}")
        for key, choices in space.items():
            option = f"--search-space {key}"
            if not isinstance(choices, list) or not 1 <= len(choices) <= MAX_CHOICES:
                raise refused(option, f"must be a list of 1 to {MAX_CHOICES} choices, got {choices!r}")
            if key in self.overrides:
                raise refused(option, "is fixed by -params: a key is either fixed or searched")
            if key in ("n_timesteps", "policy"):
                raise refused(option, "is not searched: every trial has the same budget and policy")
        for option, value, minimum in (
            ("--n-trials", self.n_trials, 1),
            ("--n-jobs", self.n_jobs, 1),
            ("--n-startup-trials", self.n_startup_trials, 0),
            ("--n-evaluations", self.n_evaluations, 1),
            ("--eval-episodes", self.eval_episodes, 1),
            ("--final-eval-episodes", self.final_eval_episodes, 1),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
                raise refused(option, f"must be an integer >= {minimum}, got {value!r}")
        max_jobs = MAX_JOBS_PER_CPU * (os.cpu_count() or 1)
        if self.n_jobs > max_jobs:
            per_cpu = f"{MAX_JOBS_PER_CPU} per CPU of this machine"
            raise refused("--n-jobs", f"must be an integer in [1, {max_jobs}] ({per_cpu}), got {self.n_jobs}")
        if self.n_timesteps is not None and self.n_timesteps < 1:
            raise refused("--n-timesteps", f"must be >= 1, got {self.n_timesteps}")
        if not self.seeds or any(seed < 0 for seed in self.seeds) or len(set(self.seeds)) != len(self.seeds):
            raise refused("--tuning-seeds", f"distinct seeds >= 0 are needed, got {list(self.seeds)}")
        self.seeds = tuple(int(seed) for seed in self.seeds)

    def evaluation_env_kwargs(self, entry_env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
        """
        The ``gym.make`` keywords of the evaluations: the entry's, then :attr:`env_kwargs`, then :attr:`eval_env_kwargs`.

        :param entry_env_kwargs: The ``env_kwargs`` of the trial's entry
        """
        return {**entry_env_kwargs, **self.env_kwargs, **self.eval_env_kwargs}

    @property
    def name(self) -> str:
        """The study's name."""
        return self.study_name or f"{self.algo}-{env_name(self.env_id)}"

    @property
    def study_dir(self) -> str:
        """The study's folder."""
        return os.path.join(self.log_folder, "tuning", self.name)

    def storage_url(self) -> str:
        """The storage, as given or the default journal file."""
        return self.storage or os.path.join(self.study_dir, "study.log")


def objective_value(settings: TuneSettings, mean_return: float, success_rate: float | None) -> float:
    """
    What an evaluation gives the study: its mean return, or its success rate (``objective="success"``).

    :raises HyperparamsError: for ``objective="success"`` where the environment reports no ``info["is_success"]``
    """
    if settings.objective == "return":
        return mean_return
    if success_rate is None:
        raise refused(
            "--objective",
            f"'success' needs episodes that end with info['is_success'], which {settings.env_id} does not report; "
            f"accepted: {', '.join(OBJECTIVE_NAMES)}",
        )
    return success_rate


def check_success_reported(settings: TuneSettings, env: gym.Env) -> None:
    """
    Check that episodes end with ``info["is_success"]``, as ``objective="success"`` needs, before anything is written.

    :param env: The evaluation environment, with the entry's wrappers (closed here)
    :raises HyperparamsError: naming ``--objective`` if the episode ends without ``is_success`` or does not end
    """
    problem = success_unreported(env)
    if problem is not None:
        raise refused(
            "--objective",
            f"'success' is the share of episodes ending with info['is_success'], but on {settings.env_id} {problem}; "
            f"accepted: {', '.join(OBJECTIVE_NAMES)}",
        )


def check_search_space(settings: TuneSettings) -> None:
    """
    Resolve every choice of ``settings.search_space`` with the starting entry, as ``-params``, before a folder is made.

    :raises HyperparamsError: naming the key and the choice
    """
    for key, choices in settings.search_space.items():
        for choice in choices:
            overrides = {**settings.overrides, key: choice}
            try:
                load_hyperparams(settings.algo, settings.env_id, settings.conf_file, overrides, settings.n_timesteps)
            except HyperparamsError as error:
                raise refused(f"--search-space {key}", f"choice {choice!r}: {error}") from None
