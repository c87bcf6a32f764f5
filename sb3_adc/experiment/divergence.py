"""
Stop a run at the first NaN or infinity (in observations, rewards, actions or weights) before it is saved: SB3's
``VecCheckNan``, its error named (:class:`NonFiniteValue`), and a check of the weights before each checkpoint.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecCheckNan, VecEnv

#: What :class:`NonFiniteValue` names as the source of a non-finite value, by the argument ``VecCheckNan`` checks.
_SOURCES = {"observations": "observation", "rewards": "reward", "dones": "done flag", "actions": "action"}


class NonFiniteValue(ValueError):
    """
    An environment returned, or was given, a NaN or an infinity (raised by :class:`FiniteCheck`).

    :param source: ``observation``, ``reward`` or ``action``
    :param kind: ``nan`` or ``inf``
    :param role: Which environments: ``training`` or ``evaluation``
    """

    def __init__(self, source: str, kind: str, role: str):
        if source == "action":
            message = f"the model's action holds {kind} (the policy's output, given to the {role} environment)"
        else:
            message = f"the {role} environment returned {kind} in its {source}"
        super().__init__(message)
        self.source = source
        self.kind = kind
        self.role = role


class TrainingDiverged(RuntimeError):
    """
    Training produced a NaN or an infinity; nothing was saved after it.

    :param run_dir: The run's folder
    :param timesteps: The timestep at which it was found
    :param source: What held it: ``observation``, ``reward``, ``action`` or ``weights``
    :param detail: What was found, in words
    :param last_checkpoint: Timestep of the newest checkpoint on disk (``None``: none)
    """

    def __init__(self, run_dir: str, timesteps: int, source: str, detail: str, last_checkpoint: int | None):
        kept = (
            f"the last good checkpoint (timestep {last_checkpoint}) is kept"
            if last_checkpoint is not None
            else "there is no checkpoint: a resume starts from scratch"
        )
        super().__init__(
            f"training diverged at timestep {timesteps}: {detail}. No model or checkpoint was saved after it; {kept}. "
            f"Fix the cause (environment, learning rate, normalization), then continue with: "
            f"sb3-adc train --resume {run_dir}"
        )
        self.run_dir = run_dir
        self.timesteps = timesteps
        self.source = source
        self.last_checkpoint = last_checkpoint


class NonFiniteWeights(ValueError):
    """
    The model's weights hold a NaN or an infinity (raised by :func:`check_finite_weights`).

    :param names: The parameters that do
    """

    def __init__(self, names: list[str]):
        super().__init__(f"the model's weights hold NaN or inf ({', '.join(names)})")
        self.names = names


class FiniteCheck(VecCheckNan):
    """
    SB3's ``VecCheckNan`` raising :class:`NonFiniteValue` (which names the source) at the first NaN or infinity
    in an observation, a reward or an action.

    :param venv: The environments
    :param role: ``training`` or ``evaluation``, for the error message
    """

    def __init__(self, venv: VecEnv, role: str = "training"):
        super().__init__(venv, raise_exception=True, check_inf=True)
        self.role = role

    def _check_val(self, event: str, **kwargs: Any) -> None:
        try:
            super()._check_val(event, **kwargs)
        except ValueError:
            for name, value in kwargs.items():
                kind = _non_finite_kind(value)
                if kind is not None:
                    raise NonFiniteValue(_SOURCES.get(name, name), kind, self.role) from None
            raise


def check_finite_weights(model: BaseAlgorithm) -> None:
    """
    Check that every parameter of the model's policy (actor, critics, targets) is finite.

    :param model: The model
    :raises NonFiniteWeights: naming the parameters that are not
    """
    names = [name for name, parameter in model.policy.named_parameters() if not bool(th.isfinite(parameter).all())]
    if names:
        raise NonFiniteWeights(names)


def _non_finite_kind(value: Any) -> str | None:
    if isinstance(value, dict):
        value = list(value.values())
    if isinstance(value, (list, tuple)):
        return next((kind for kind in map(_non_finite_kind, value) if kind is not None), None)
    array = np.asarray(value)
    if not np.issubdtype(array.dtype, np.number):
        return None
    if np.isnan(array).any():
        return "nan"
    return "inf" if np.isinf(array).any() else None
