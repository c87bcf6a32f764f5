"""
The keys a hyperparameter entry accepts, and the type of each.

An entry accepts the RL-Zoo keys of :data:`EXPERIMENT_KEYS` (read by the tooling, not passed to the model),
the keyword arguments of the algorithm's constructor (checked with :data:`MODEL_KEYS` where the type is
known, else any YAML scalar), ADC's top-level policy keys (:data:`ADC_POLICY_KEYS`) for ADC, and the
exploration-noise keys for algorithms that take ``action_noise``.
"""

from __future__ import annotations

import inspect

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

from sb3_adc.adc.intervals import AGGREGATIONS, INTERPOLATIONS, check_n_intervals
from sb3_adc.adc.options import (
    check_actor_greedy_weight,
    check_fast_update,
    check_interval_exploration,
    check_interval_temperature,
    check_target_greedy_mix,
)
from sb3_adc.adc.policies import CRITIC_DESIGNS
from sb3_adc.common.actor_average import ActorAverageTD3Policy, check_actor_average_tau
from sb3_adc.config import validators as v
from sb3_adc.config.errors import HyperparamsError

#: The most environments of a run (``n_envs``): each one is a process with ``vec_env: subproc`` and holds a monitor
#: file open, and operating systems allow a process 1024 open files by default.
MAX_N_ENVS = 256
#: The most transitions a replay buffer holds (``buffer_size``); :data:`MAX_REPLAY_BUFFER_BYTES` bounds its memory.
MAX_BUFFER_SIZE = 100_000_000
#: The most transitions a gradient step samples (``batch_size``).
MAX_BATCH_SIZE = 1_000_000
#: The most memory a replay buffer may need, as estimated by :func:`replay_buffer_bytes` (64 GiB).
MAX_REPLAY_BUFFER_BYTES = 64 * 2**30
#: The most units of a hidden layer (``net_arch`` and the other layer lists of ``policy_kwargs``).
MAX_LAYER_WIDTH = 16_384
#: The most weights between the hidden layers of one network, ``sum(w[i] * w[i + 1])`` (400 MB in float32).
MAX_HIDDEN_WEIGHTS = 100_000_000

#: RL-Zoo keys read by the experiment tooling itself.
EXPERIMENT_KEYS: dict[str, v.Validator] = {
    "n_timesteps": v.integer(1),
    "policy": v.string,
    "n_envs": v.integer(1, maximum=MAX_N_ENVS),
    "policy_kwargs": v.mapping_or_expression,
    "normalize": v.normalize,
    "frame_stack": v.optional(v.integer(1)),
    "env_wrapper": v.optional(v.class_reference),
    "env_kwargs": v.mapping,
    "callback": v.optional(v.class_reference),
}

#: Exploration noise keys (algorithms with an ``action_noise`` argument).
NOISE_TYPES = ("normal", "ornstein-uhlenbeck", "epsilon-normal")
NOISE_KEYS: dict[str, v.Validator] = {
    "noise_type": v.optional(v.choice(*NOISE_TYPES)),
    "noise_std": v.noise_std,
}
#: Keys of ``noise_type: epsilon-normal`` (:class:`~sb3_adc.common.noise.EpsilonGaussianNoise`).
EPSILON_NOISE_KEYS: dict[str, v.Validator] = {
    "epsilon_decay_steps": v.integer(0),
    "epsilon_initial": v.real(0.0, 1.0),
    "epsilon_final": v.real(0.0, 1.0),
}

#: ADC policy options accepted at the top level of an entry (merged into ``policy_kwargs``).
#: The accepted values come from the critic (:mod:`sb3_adc.adc.policies`, which also checks how they combine).
ADC_POLICY_KEYS: dict[str, v.Validator] = {
    "n_intervals": v.checked_by(check_n_intervals, v.integer()),
    "aggregation": v.choice(*AGGREGATIONS),
    "advantage_interpolation": v.choice(*INTERPOLATIONS),
    "critic_design": v.choice(*CRITIC_DESIGNS),
    "basis_degree": v.integer(1),
    "actor_average_tau": v.checked_by(check_actor_average_tau, v.real()),
}

#: Types of the constructor keywords of the supported algorithms (others accept any YAML scalar).
MODEL_KEYS: dict[str, v.Validator] = {
    "learning_rate": v.learning_rate,
    "critic_learning_rate": v.optional(v.learning_rate),
    "buffer_size": v.integer(1, maximum=MAX_BUFFER_SIZE),
    "batch_size": v.integer(1, maximum=MAX_BATCH_SIZE),
    "learning_starts": v.integer(0),
    "gamma": v.real(0.0, 1.0),
    "tau": v.real(0.0, 1.0),
    "train_freq": v.train_freq,
    "gradient_steps": v.integer(1, allowed=(-1,)),
    "n_steps": v.integer(1),
    "policy_delay": v.integer(1),
    "top_quantiles_to_drop_per_net": v.integer(0),  # TQC's
    "target_policy_noise": v.real(0.0),
    "target_noise_clip": v.real(0.0),
    "target_greedy_mix": v.checked_by(check_target_greedy_mix, v.real()),
    "actor_greedy_weight": v.checked_by(check_actor_greedy_weight, v.real()),
    "interval_exploration": v.checked_by(check_interval_exploration, v.real()),
    "interval_temperature": v.checked_by(check_interval_temperature, v.real()),
    "fast_update": v.checked_by(check_fast_update, v.boolean),
    "optimize_memory_usage": v.boolean,
    "replay_buffer_class": v.optional(v.string),
    "replay_buffer_kwargs": v.optional(v.mapping_or_expression),
    "stats_window_size": v.integer(1),
    "ent_coef": v.entropy_coefficient,
    "target_entropy": v.target_entropy,
    "target_update_interval": v.integer(1),
    "use_sde": v.boolean,
    "sde_sample_freq": v.integer(-1),
    "use_sde_at_warmup": v.boolean,
    "exploration_fraction": v.real(0.0, 1.0),
    "exploration_initial_eps": v.real(0.0, 1.0),
    "exploration_final_eps": v.real(0.0, 1.0),
    "max_grad_norm": v.real(0.0, exclusive_minimum=True),
}

#: Layer lists of ``policy_kwargs``, checked for every algorithm: SB3's ``net_arch``, and the value and advantage
#: streams of ADC's and the dueling DQN's networks.
LAYER_KEYS: dict[str, v.Validator] = {
    name: v.layer_sizes(MAX_LAYER_WIDTH, MAX_HIDDEN_WEIGHTS) for name in ("net_arch", "value_net_arch", "advantage_net_arch")
}

#: Constructor keywords set by the tooling (or by the noise keys), never by an entry.
RESERVED_MODEL_KEYS = frozenset(
    {
        "self",
        "policy",
        "env",
        "policy_kwargs",
        "action_noise",
        "seed",
        "verbose",
        "device",
        "tensorboard_log",
        "_init_setup_model",
    }
)


def constructor_keys(algorithm_class: type[BaseAlgorithm]) -> list[str]:
    """
    The keyword arguments of an algorithm's constructor that an entry may set.

    :param algorithm_class: The algorithm
    """
    parameters = inspect.signature(algorithm_class.__init__).parameters.values()
    return [
        parameter.name
        for parameter in parameters
        if parameter.name not in RESERVED_MODEL_KEYS
        and parameter.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    ]


def takes_action_noise(algorithm_class: type[BaseAlgorithm]) -> bool:
    """
    Whether the algorithm's constructor has an ``action_noise`` argument.

    :param algorithm_class: The algorithm
    """
    return "action_noise" in inspect.signature(algorithm_class.__init__).parameters


def accepted_keys(algorithm_class: type[BaseAlgorithm], adc_keys: bool) -> dict[str, v.Validator]:
    """
    Every key an entry for this algorithm accepts, with its validator.

    :param algorithm_class: The algorithm
    :param adc_keys: Whether ADC's top-level policy keys are accepted
    """
    keys: dict[str, v.Validator] = dict(EXPERIMENT_KEYS)
    for name in constructor_keys(algorithm_class):
        keys[name] = MODEL_KEYS.get(name, v.scalar)
    if takes_action_noise(algorithm_class):
        keys.update(NOISE_KEYS)
        keys.update(EPSILON_NOISE_KEYS)
    if adc_keys:
        keys.update(ADC_POLICY_KEYS)
    return keys


def policy_kwargs_keys(algorithm_class: type[BaseAlgorithm], adc_keys: bool) -> dict[str, v.Validator]:
    """
    The ``policy_kwargs`` keys checked when the entry is read (with the validators of the same options at the top
    level), so that a wrong value is an error naming the key rather than a traceback when the model is built:
    ADC's policy options for ADC, ``actor_average_tau`` for an algorithm whose ``MlpPolicy`` keeps an averaged actor
    (TD3). Other keys are the policy's to check.

    The layer lists (:data:`LAYER_KEYS`) are checked for every algorithm.

    :param algorithm_class: The algorithm
    :param adc_keys: Whether ADC's policy options are accepted
    """
    if adc_keys:
        return {**LAYER_KEYS, **ADC_POLICY_KEYS}
    mlp_policy = getattr(algorithm_class, "policy_aliases", {}).get("MlpPolicy")
    if isinstance(mlp_policy, type) and issubclass(mlp_policy, ActorAverageTD3Policy):
        return {**LAYER_KEYS, "actor_average_tau": ADC_POLICY_KEYS["actor_average_tau"]}
    return dict(LAYER_KEYS)


def _space_bytes(space: spaces.Space) -> int:
    """Bytes of one element of ``space`` in a replay buffer (the sum of its parts for a ``Dict`` space)."""
    if isinstance(space, spaces.Dict):
        return sum(_space_bytes(part) for part in space.spaces.values())
    dtype = np.dtype(space.dtype if space.dtype is not None else np.float32)
    return int(np.prod(space.shape or (1,), dtype=np.int64)) * dtype.itemsize


def replay_buffer_bytes(
    buffer_size: int, observation_space: spaces.Space, action_space: spaces.Space, optimize_memory_usage: bool = False
) -> int:
    """
    The memory an SB3 replay buffer of ``buffer_size`` transitions allocates: observations (twice, for the next
    observations, unless ``optimize_memory_usage``), actions, and four ``float32`` values (reward, done, timeout and
    alignment) per transition.

    :param buffer_size: Transitions held
    :param observation_space: The environment's observation space
    :param action_space: The environment's action space
    :param optimize_memory_usage: Whether the next observations share the observations' array
    """
    observations = _space_bytes(observation_space) * (1 if optimize_memory_usage else 2)
    return buffer_size * (observations + _space_bytes(action_space) + 16)


def check_replay_buffer(model: BaseAlgorithm, source: str) -> None:
    """
    Check that the replay buffer of an algorithm built with ``_init_setup_model=False`` fits in
    :data:`MAX_REPLAY_BUFFER_BYTES`, before it is allocated (algorithms without one pass).

    :param model: The algorithm, with its spaces and ``buffer_size``
    :param source: Where ``buffer_size`` was read, for the error message
    :raises HyperparamsError: naming ``buffer_size``, the estimate and the largest ``buffer_size`` that fits
    """
    if not isinstance(model, OffPolicyAlgorithm):
        return
    optimize = bool(model.optimize_memory_usage)
    needed = replay_buffer_bytes(model.buffer_size, model.observation_space, model.action_space, optimize)
    if needed > MAX_REPLAY_BUFFER_BYTES:
        per_transition = replay_buffer_bytes(1, model.observation_space, model.action_space, optimize)
        raise HyperparamsError(
            source,
            "buffer_size",
            f"a replay buffer of {model.buffer_size} transitions of {per_transition} bytes (observations of shape "
            f"{model.observation_space.shape}) needs about {needed / 2**30:.1f} GiB, more than MAX_REPLAY_BUFFER_BYTES="
            f"{MAX_REPLAY_BUFFER_BYTES // 2**30} GiB of sb3_adc.config.schema; accepted: buffer_size <= "
            f"{MAX_REPLAY_BUFFER_BYTES // per_transition} for these spaces",
        )
