"""
The names a hyperparameter file may refer to (``name -> "module:attribute"``, imported on first use). Add your own from
Python with :meth:`AllowList.add`, for example ``ENV_WRAPPERS.add("my_pkg.MyWrapper", MyWrapper)``.
"""

from __future__ import annotations

import pkgutil

from sb3_adc.config.errors import HyperparamsError


class AllowList:
    """
    A named set of objects that configuration values may refer to by name.

    :param kind: What the names are (used in error messages), e.g. ``"environment wrapper"``
    :param targets: ``name -> "module:attribute"``; the module is imported on first use of the name
    """

    def __init__(self, kind: str, targets: dict[str, str]):
        self.kind = kind
        self._targets: dict[str, str | object] = dict(targets)

    def __repr__(self) -> str:
        return f"AllowList({self.kind!r}, {len(self._targets)} names)"

    def __contains__(self, name: object) -> bool:
        return name in self._targets

    def names(self) -> list[str]:
        """The accepted names, sorted."""
        return sorted(self._targets)

    def add(self, name: str, target: object) -> None:
        """
        Accept one more name.

        :param name: The name configuration files will use (a dotted path such as ``"my_pkg.MyWrapper"``)
        :param target: The object itself, or where to import it from as ``"module:attribute"``
        """
        if not isinstance(name, str) or not name:
            raise ValueError(f"AllowList.add: `name` must be a non-empty string, got {name!r}.")
        self._targets[name] = target

    def remove(self, name: str) -> None:
        """
        Stop accepting a name.

        :param name: A name added before
        :raises KeyError: if the name is not in the list
        """
        del self._targets[name]

    def resolve(self, name: str, source: str, key: str) -> object:
        """
        The object a name stands for.

        :param name: The name as written in the configuration
        :param source: Where the name was read (for the error message)
        :param key: The hyperparameter key (for the error message)
        :raises HyperparamsError: if the name is not in the list
        """
        if name not in self._targets:
            accepted = ", ".join(self.names())
            raise HyperparamsError(source, key, f"unknown {self.kind} {name!r}; accepted: {accepted}", expression=name)
        target = self._targets[name]
        if isinstance(target, str):  # imported on first use
            target = self._targets[name] = pkgutil.resolve_name(target)
        return target


def _prefixed(module: str, attributes: str, prefixes: tuple[str, ...] | None = None) -> dict[str, str]:
    """``prefix + attribute -> "module:attribute"`` for each of the space-separated attributes (prefix: ``module.``)."""
    prefixes = prefixes or (f"{module}.",)
    return {f"{prefix}{attribute}": f"{module}:{attribute}" for prefix in prefixes for attribute in attributes.split()}


_ACTIVATIONS = "ReLU Tanh ELU LeakyReLU SELU SiLU GELU Sigmoid Softplus Mish Hardtanh Identity"
_TORCH_LAYERS = "stable_baselines3.common.torch_layers"
#: Names usable inside expressions (``policy_kwargs``, ``replay_buffer_kwargs``, ``normalize`` strings):
#: torch activation functions and optimizers, SB3 features extractors and optimizers.
EXPRESSION_NAMES = AllowList(
    "name",
    {
        **_prefixed("torch.nn", _ACTIVATIONS, ("nn.", "th.nn.", "torch.nn.")),
        **_prefixed("torch.optim", "Adam AdamW SGD RMSprop", ("th.optim.", "torch.optim.")),
        **_prefixed(_TORCH_LAYERS, "FlattenExtractor NatureCNN CombinedExtractor", ("", f"{_TORCH_LAYERS}.")),
        **_prefixed("stable_baselines3.common.sb2_compat.rmsprop_tf_like", "RMSpropTFLike", ("",)),
    },
)
#: Values of ``replay_buffer_class``.
REPLAY_BUFFERS = AllowList(
    "replay buffer class",
    {
        **_prefixed("stable_baselines3.common.buffers", "ReplayBuffer", ("", "stable_baselines3.common.buffers.")),
        **_prefixed("stable_baselines3", "HerReplayBuffer", ("", "stable_baselines3.")),
    },
)
#: Values of ``env_wrapper`` (Gymnasium wrappers applied to each environment, in order).
ENV_WRAPPERS = AllowList(
    "environment wrapper",
    {
        **_prefixed("sb3_adc_envs.wrappers", "ClearanceShaping DiscretizedActions UniformObservationNoise"),
        **_prefixed("sb3_contrib.common.wrappers", "TimeFeatureWrapper"),
        **_prefixed("gymnasium.wrappers", "ClipAction RescaleAction FlattenObservation TimeLimit FrameStackObservation"),
    },
)
#: Values of ``callback`` (SB3 callbacks added to training).
CALLBACKS = AllowList(
    "callback",
    {
        **_prefixed("stable_baselines3.common.callbacks", "CheckpointCallback StopTrainingOnMaxEpisodes LogEveryNTimesteps"),
        **_prefixed("sb3_adc.diagnostics", "CriticDiagnosticsCallback"),
    },
)
#: ``policy`` values besides the algorithm's own aliases (``MlpPolicy``, ``CnnPolicy``, ...).
POLICIES = AllowList("policy", {"sb3_adc.baselines.DuelingDQNPolicy": "sb3_adc.baselines.dueling_dqn:DuelingDQNPolicy"})
