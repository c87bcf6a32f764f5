"""
The final evaluation of a trained model: mean and standard deviation of the return over deterministic episodes,
and the success rate where the environment reports ``info["is_success"]`` at the end of an episode.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import VecEnv

from sb3_adc.common.atomic import write_atomically


def success_rate(successes: Sequence[bool] | None) -> float | None:
    """
    The share of episodes that ended with ``info["is_success"]`` (SB3's ``eval/success_rate``), or ``None`` where
    the episodes reported none (``None`` or no episode: no rate, rather than numpy's NaN of an empty mean).

    :param successes: ``info["is_success"]`` at the end of each episode
    """
    return float(np.mean(successes)) if successes else None


@dataclass
class FinalEvaluation:
    """
    Returns of the final model over deterministic episodes.

    :param algo: The algorithm's name
    :param env_id: The environment id
    :param seed: The run's seed
    :param timesteps: Timesteps the model was trained for
    :param returns: Return of each episode
    :param lengths: Length of each episode
    :param successes: ``info["is_success"]`` at the end of each episode, where the environment reports it (the
        lidar courses do), else ``None``
    """

    algo: str
    env_id: str
    seed: int
    timesteps: int
    returns: list[float]
    lengths: list[int]
    successes: list[bool] | None = None

    @property
    def mean_return(self) -> float:
        return float(np.mean(self.returns))

    @property
    def std_return(self) -> float:
        return float(np.std(self.returns))

    @property
    def success_rate(self) -> float | None:
        """The share of successful episodes, or ``None`` where the environment reports no success."""
        return success_rate(self.successes)

    def summary(self) -> str:
        """One line: ``Final evaluation of adc on Pendulum-v1 (seed 0, 20000 steps): -152.3 +/- 80.1 ...``."""
        success = "" if self.success_rate is None else f", success rate {self.success_rate:.2f}"
        return (
            f"Final evaluation of {self.algo} on {self.env_id} (seed {self.seed}, {self.timesteps} steps): "
            f"mean return {self.mean_return:.2f} +/- {self.std_return:.2f} over {len(self.returns)} deterministic episodes"
            f"{success}"
        )

    def save(self, path: str) -> None:
        """
        Write the evaluation as JSON (with its mean and std), atomically.

        :param path: The file
        """
        data = {**asdict(self), "mean_return": self.mean_return, "std_return": self.std_return}
        if self.successes is None:
            del data["successes"]  # the file of an environment without successes stays as it was
        else:
            data["success_rate"] = self.success_rate
        write_atomically(path, lambda stream: json.dump(data, stream, indent=2))

    @classmethod
    def load(cls, path: str) -> FinalEvaluation:
        """
        Read an evaluation written by :meth:`save`.

        :param path: The file
        """
        with open(path, encoding="utf-8") as stream:
            data = json.load(stream)
        return cls(
            **{key: data[key] for key in ("algo", "env_id", "seed", "timesteps", "returns", "lengths")},
            successes=data.get("successes"),
        )


def evaluate_final(model: BaseAlgorithm, env: VecEnv, n_episodes: int, algo: str, env_id: str, seed: int) -> FinalEvaluation:
    """
    Run ``n_episodes`` deterministic episodes of ``model`` on ``env``.

    :param model: The trained model
    :param env: The evaluation environments (statistics of ``VecNormalize`` already synced, updates off)
    :param n_episodes: Number of episodes
    :param algo: The algorithm's name (recorded)
    :param env_id: The environment id (recorded)
    :param seed: The run's seed (recorded)
    """
    successes: list[bool] = []

    def record_success(local: dict[str, Any], _: dict[str, Any]) -> None:
        # What SB3's EvalCallback records for its success rate: ``is_success`` of the info that ends an episode.
        if local["done"] and local["info"].get("is_success") is not None:
            successes.append(bool(local["info"]["is_success"]))

    returns, lengths = evaluate_policy(
        model, env, n_eval_episodes=n_episodes, deterministic=True, return_episode_rewards=True, callback=record_success
    )
    episode_returns = [float(value) for value in np.atleast_1d(returns)]
    return FinalEvaluation(
        algo=algo,
        env_id=env_id,
        seed=seed,
        timesteps=int(model.num_timesteps),
        returns=episode_returns,
        lengths=[int(value) for value in np.atleast_1d(lengths)],
        successes=successes if len(successes) == len(episode_returns) else None,
    )


#: Longest episode of random actions with which :func:`success_unreported` looks for ``info["is_success"]``.
SUCCESS_PROBE_MAX_STEPS = 10_000


def success_unreported(env: gym.Env) -> str | None:
    """
    Why success rates cannot be measured on ``env``, or ``None`` if they can: one episode of random actions must end
    with ``info["is_success"]`` in its last step, which SB3's evaluations read. Options that need a success rate
    (the tuning's ``objective="success"``, ``best_model_metric="success"``) ask this before anything is written.

    :param env: An evaluation environment, with the entry's wrappers (closed here)
    """
    try:
        env.reset(seed=0)
        env.action_space.seed(0)
        for _ in range(SUCCESS_PROBE_MAX_STEPS):
            _, _, terminated, truncated, info = env.step(env.action_space.sample())
            if terminated or truncated:
                return None if info.get("is_success") is not None else "its episodes end without info['is_success']"
    finally:
        env.close()
    return f"no episode ended within {SUCCESS_PROBE_MAX_STEPS} random steps"
