"""The RL Zoo's ``ExperimentManager`` with hyperparameters read by :mod:`sb3_adc.config` (nothing ``eval``'d)."""

from __future__ import annotations

import os
import sys
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from pprint import pprint
from typing import Any

import optuna
import yaml
from gymnasium import spaces
from rl_zoo3.exp_manager import ExperimentManager
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from sb3_adc.common.atomic import write_atomically
from sb3_adc.config import ExperimentConfig, load_hyperparams, packaged_hyperparams_file, resolve_entry
from sb3_adc.experiment.samplers import SAMPLERS, Space
from sb3_adc.experiment.tuning import trial_entry


class SafeExperimentManager(ExperimentManager):
    """
    ``rl_zoo3.exp_manager.ExperimentManager`` reading its hyperparameters with :mod:`sb3_adc.config`.

    The Zoo's own reading ``eval``s ``policy_kwargs``, ``normalize`` and ``monitor_kwargs`` strings and imports
    whatever ``env_wrapper``/``callback``/``policy`` names. Here the entry (default: sb3-adc's shipped
    ``{algo}.yml``; ``-conf FILE`` for another) is validated and resolved by
    :func:`~sb3_adc.config.load_hyperparams`, ``-params`` overrides included, and the Zoo receives Python
    objects. Everything else (environments, callbacks, evaluation, saving, the log layout) is the Zoo's.
    ``config.yml`` and ``args.yml`` are written as plain YAML (the Zoo writes Python tags).
    """

    def __init__(self, *args: Any, **kwargs: Any):
        conf_file = kwargs.get("config")
        super().__init__(*args, **kwargs)
        self.config = conf_file or packaged_hyperparams_file(self.algo)
        self.cli_env_kwargs = dict(self.env_kwargs)
        self.experiment: ExperimentConfig | None = None

    def read_hyperparameters(self) -> tuple[dict[str, Any], dict[str, Any]]:
        print(f"Loading hyperparameters from: {self.config}")
        self.experiment = load_hyperparams(
            self.algo,
            self.env_name.gym_id,
            conf_file=self.config,
            overrides=self.custom_hyperparams,
            n_timesteps=self.n_timesteps if self.n_timesteps > 0 else None,
        )
        saved = OrderedDict(sorted(self.experiment.saved.items()))
        print("Default hyperparameters for environment (ones being tuned will be overridden):")
        pprint(dict(saved))
        return dict(saved), saved

    def _preprocess_hyperparams(
        self, hyperparams: dict[str, Any]
    ) -> tuple[dict[str, Any], Callable | None, list[BaseCallback], Callable | None]:
        experiment = self._experiment()
        self.n_envs = experiment.n_envs
        if self.verbose > 0:
            print(f"Using {self.n_envs} environments")
        self.n_timesteps = experiment.n_timesteps
        if experiment.normalize is not None:
            self.normalize = True
            self.normalize_kwargs = dict(experiment.normalize)
        # Command-line --env-kwargs replace the entry's values.
        self.env_kwargs = {**experiment.env_kwargs, **self.cli_env_kwargs}
        if self._eval_env_kwargs_args is None:
            self.eval_env_kwargs = self.env_kwargs
        self.frame_stack = experiment.frame_stack  # type: ignore[assignment]  # the Zoo declares it None
        env_wrapper = experiment.wrap_env if experiment.env_wrappers else None
        return dict(experiment.model_kwargs), env_wrapper, experiment.make_callbacks(), None

    def _preprocess_action_noise(
        self, hyperparams: dict[str, Any], saved_hyperparams: dict[str, Any], env: VecEnv
    ) -> dict[str, Any]:
        if isinstance(env.action_space, spaces.Box):
            self.n_actions = env.action_space.shape[0]
        experiment = self._experiment()
        if experiment.noise is not None:
            hyperparams["action_noise"] = experiment.make_action_noise(env.action_space)
            print(f"Applying {experiment.noise.noise_type} noise with std {experiment.noise.std}")
        return hyperparams

    def hyperparameters_optimization(self) -> None:
        """
        The Zoo's ``-optimize``, drawing from sb3-adc's search spaces (:mod:`sb3_adc.experiment.samplers`).

        The Zoo takes samplers only through its ``HYPERPARAMS_SAMPLER`` table, so this registers an adapter for
        ``self.algo`` there (as ``ALGOS`` is extended for the algorithms): each draw is merged into the entry and
        resolved by :func:`~sb3_adc.config.resolve_entry`, which validates it and builds the exploration noise.
        """
        from rl_zoo3.hyperparams_opt import HYPERPARAMS_SAMPLER

        HYPERPARAMS_SAMPLER[self.algo] = self._sample_hyperparams
        super().hyperparameters_optimization()

    def _sample_hyperparams(
        self, trial: optuna.Trial, n_actions: int, n_envs: int, additional_args: dict[str, Any]
    ) -> dict[str, Any]:
        """A draw of sb3-adc's search space, as constructor keywords (the Zoo's sampler signature)."""
        base = dict(self._experiment().saved)
        fixed = self.custom_hyperparams or {}
        params = SAMPLERS[self.algo](Space(trial, base, fixed))
        entry = trial_entry(base, params, fixed)
        config = resolve_entry(self.algo, self.env_name.gym_id, entry, f"trial {trial.number}")
        kwargs = dict(config.model_kwargs)
        if config.noise is not None:
            kwargs["action_noise"] = config.make_action_noise(spaces.Box(-1.0, 1.0, (n_actions,)))
        return kwargs

    def _save_config(self, saved_hyperparams: dict[str, Any]) -> None:
        config_text = yaml.safe_dump(dict(self._experiment().saved), sort_keys=True)
        args_text = yaml.safe_dump(dict(sorted(vars(self.args).items())))
        write_atomically(os.path.join(self.params_path, "config.yml"), lambda stream: stream.write(config_text))
        write_atomically(os.path.join(self.params_path, "args.yml"), lambda stream: stream.write(args_text))
        (Path(self.params_path) / "command.txt").write_text(" ".join(getattr(sys, "orig_argv", sys.argv)))
        print(f"Log path: {self.save_path}")

    def _experiment(self) -> ExperimentConfig:
        if self.experiment is None:
            raise RuntimeError("read_hyperparameters() must run first")
        return self.experiment
