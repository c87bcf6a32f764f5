"""The keys a hyperparameter entry accepts (see :func:`entry_keys`), the type of each, and the bounds on memory."""

from __future__ import annotations

import inspect

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

from sb3_adc.adc import ADC, options
from sb3_adc.adc.intervals import AGGREGATIONS, INTERPOLATIONS, check_n_intervals
from sb3_adc.adc.policies import CRITIC_DESIGNS
from sb3_adc.common.actor_average import ActorAverageTD3Policy, check_actor_average_tau
from sb3_adc.config import validators as v
from sb3_adc.config.errors import HyperparamsError

#: The most environments of a run (``n_envs``): each is a process (``vec_env: subproc``) holding a monitor file open.
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
    "env_kwargs": v.mapping,
    **dict.fromkeys(("env_wrapper", "callback"), v.optional(v.class_reference)),
}

#: Exploration noise keys (algorithms with an ``action_noise`` argument).
NOISE_TYPES = ("normal", "ornstein-uhlenbeck", "epsilon-normal")
NOISE_KEYS: dict[str, v.Validator] = {"noise_type": v.optional(v.choice(*NOISE_TYPES)), "noise_std": v.noise_std}
#: Keys of ``noise_type: epsilon-normal`` (:class:`~sb3_adc.common.noise.EpsilonGaussianNoise`).
EPSILON_NOISE_KEYS: dict[str, v.Validator] = {
    "epsilon_decay_steps": v.integer(0),
    **dict.fromkeys(("epsilon_initial", "epsilon_final"), v.real(0.0, 1.0)),
}

#: ADC policy options accepted at the top level of an entry (merged into ``policy_kwargs``; values from the critic's).
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
    **dict.fromkeys(
        ("gamma", "tau", "exploration_fraction", "exploration_initial_eps", "exploration_final_eps"), v.real(0.0, 1.0)
    ),
    **dict.fromkeys(("n_steps", "policy_delay", "stats_window_size", "target_update_interval"), v.integer(1)),
    **dict.fromkeys(("learning_starts", "top_quantiles_to_drop_per_net"), v.integer(0)),  # the latter is TQC's
    **dict.fromkeys(("target_policy_noise", "target_noise_clip"), v.real(0.0)),
    **dict.fromkeys(("optimize_memory_usage", "use_sde", "use_sde_at_warmup"), v.boolean),
    "learning_rate": v.learning_rate,
    "critic_learning_rate": v.optional(v.learning_rate),
    "buffer_size": v.integer(1, maximum=MAX_BUFFER_SIZE),
    "batch_size": v.integer(1, maximum=MAX_BATCH_SIZE),
    "train_freq": v.train_freq,
    "gradient_steps": v.integer(1, allowed=(-1,)),
    "target_greedy_mix": v.checked_by(options.check_target_greedy_mix, v.real()),
    "actor_greedy_weight": v.checked_by(options.check_actor_greedy_weight, v.real()),
    "interval_exploration": v.checked_by(options.check_interval_exploration, v.real()),
    "interval_temperature": v.checked_by(options.check_interval_temperature, v.real()),
    "fast_update": v.checked_by(options.check_fast_update, v.boolean),
    "replay_buffer_class": v.optional(v.string),
    "replay_buffer_kwargs": v.optional(v.mapping_or_expression),
    "ent_coef": v.entropy_coefficient,
    "target_entropy": v.target_entropy,
    "sde_sample_freq": v.integer(-1),
    "max_grad_norm": v.real(0.0, exclusive_minimum=True),
}

#: Layer lists of ``policy_kwargs``, checked for every algorithm (SB3's ``net_arch``, ADC's and dueling DQN's streams).
LAYER_KEYS: dict[str, v.Validator] = {
    name: v.layer_sizes(MAX_LAYER_WIDTH, MAX_HIDDEN_WEIGHTS) for name in ("net_arch", "value_net_arch", "advantage_net_arch")
}

#: Constructor keywords set by the tooling (or by the noise keys), never by an entry.
RESERVED_MODEL_KEYS = frozenset(
    {"self", "policy", "env", "policy_kwargs", "action_noise", "seed", "verbose", "device", "tensorboard_log"}
) | {"_init_setup_model"}


def entry_keys(algorithm_class: type[BaseAlgorithm]) -> tuple[dict[str, v.Validator], dict[str, v.Validator], list[str]]:
    """
    The keys an entry accepts, with their validators (constructor keywords not in :data:`MODEL_KEYS` take any scalar);
    the ``policy_kwargs`` keys checked on reading (others are the policy's to check); the constructor's keywords.

    :param algorithm_class: The algorithm
    """
    parameters = inspect.signature(algorithm_class.__init__).parameters.values()
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    constructor = [param.name for param in parameters if param.kind in kinds and param.name not in RESERVED_MODEL_KEYS]
    accepted = {**EXPERIMENT_KEYS, **{name: MODEL_KEYS.get(name, v.scalar) for name in constructor}}
    if any(parameter.name == "action_noise" for parameter in parameters):
        accepted.update({**NOISE_KEYS, **EPSILON_NOISE_KEYS})
    if issubclass(algorithm_class, ADC):
        return {**accepted, **ADC_POLICY_KEYS}, {**LAYER_KEYS, **ADC_POLICY_KEYS}, constructor
    mlp_policy = getattr(algorithm_class, "policy_aliases", {}).get("MlpPolicy")
    if isinstance(mlp_policy, type) and issubclass(mlp_policy, ActorAverageTD3Policy):
        return accepted, {**LAYER_KEYS, "actor_average_tau": ADC_POLICY_KEYS["actor_average_tau"]}, constructor
    return accepted, dict(LAYER_KEYS), constructor


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
    The memory an SB3 replay buffer of ``buffer_size`` transitions allocates: observations (twice unless
    ``optimize_memory_usage``), actions, and four ``float32`` (reward, done, timeout, alignment) per transition.

    :param buffer_size: Transitions held
    :param observation_space: The environment's observation space
    :param action_space: The environment's action space
    :param optimize_memory_usage: Whether the next observations share the observations' array
    """
    observations = _space_bytes(observation_space) * (1 if optimize_memory_usage else 2)
    return buffer_size * (observations + _space_bytes(action_space) + 16)


def check_replay_buffer(model: BaseAlgorithm, source: str) -> None:
    """
    Check, before it is allocated, that the replay buffer of an algorithm built with ``_init_setup_model=False`` fits
    in :data:`MAX_REPLAY_BUFFER_BYTES` (algorithms without one pass).

    :param model: The algorithm, with its spaces and ``buffer_size``
    :param source: Where ``buffer_size`` was read, for the error message
    :raises HyperparamsError: naming ``buffer_size``, the estimate and the largest ``buffer_size`` that fits
    """
    if not isinstance(model, OffPolicyAlgorithm):
        return
    per_transition = replay_buffer_bytes(1, model.observation_space, model.action_space, bool(model.optimize_memory_usage))
    needed = model.buffer_size * per_transition
    if needed > MAX_REPLAY_BUFFER_BYTES:
        shape = model.observation_space.shape
        transitions = f"{model.buffer_size} transitions of {per_transition} bytes (observations of shape {shape})"
        limit = f"MAX_REPLAY_BUFFER_BYTES={MAX_REPLAY_BUFFER_BYTES // 2**30} GiB of sb3_adc.config.schema"
        accepted = f"accepted: buffer_size <= {MAX_REPLAY_BUFFER_BYTES // per_transition} for these spaces"
        problem = f"a replay buffer of {transitions} needs about {needed / 2**30:.1f} GiB, more than {limit}; {accepted}"
        raise HyperparamsError(source, "buffer_size", problem)
