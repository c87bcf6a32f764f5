"""The final evaluation of a trained model, with the success rate where reported."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import gymnasium as gym
import numpy as np

from sb3_adc.common.atomic import write_atomically


def success_rate(successes: Sequence[bool] | None) -> float | None:
    """
    The share of episodes that ended with ``info["is_success"]`` (SB3's ``eval/success_rate``; ``None``: none reported).

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
    :param successes: ``info["is_success"]`` at the end of each episode, where reported, else ``None``
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
        """Read an evaluation written by :meth:`save`."""
        with open(path, encoding="utf-8") as stream:
            data = json.load(stream)
        return cls(
            **{key: data[key] for key in ("algo", "env_id", "seed", "timesteps", "returns", "lengths")},
            successes=data.get("successes"),
        )


#: Longest episode of random actions with which :func:`success_unreported` looks for ``info["is_success"]``.
SUCCESS_PROBE_MAX_STEPS = 10_000


def success_unreported(env: gym.Env) -> str | None:
    """
    Why success rates cannot be measured on ``env``, or ``None`` if they can: one episode of random actions must end
    with ``info["is_success"]``. Options that need a success rate ask this before anything is written.

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
