"""
The keys a hyperparameter entry accepts, and the type of each.

An entry accepts the RL-Zoo keys of :data:`EXPERIMENT_KEYS` (read by the tooling, not passed to the model),
the keyword arguments of the algorithm's constructor (checked with :data:`MODEL_KEYS` where the type is
known, else any YAML scalar), ADC's top-level policy keys (:data:`ADC_POLICY_KEYS`) for ADC, and the
exploration-noise keys for algorithms that take ``action_noise``.
"""

from __future__ import annotations

import inspect

from stable_baselines3.common.base_class import BaseAlgorithm

from sb3_adc.adc.adc import check_actor_greedy_weight, check_fast_update, check_target_greedy_mix
from sb3_adc.adc.intervals import AGGREGATIONS, INTERPOLATIONS, check_n_intervals
from sb3_adc.adc.policies import CRITIC_DESIGNS
from sb3_adc.common.actor_average import ActorAverageTD3Policy, check_actor_average_tau
from sb3_adc.config import validators as v

#: RL-Zoo keys read by the experiment tooling itself.
EXPERIMENT_KEYS: dict[str, v.Validator] = {
    "n_timesteps": v.integer(1),
    "policy": v.string,
    "n_envs": v.integer(1),
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
    "buffer_size": v.integer(1),
    "batch_size": v.integer(1),
    "learning_starts": v.integer(0),
    "gamma": v.real(0.0, 1.0),
    "tau": v.real(0.0, 1.0),
    "train_freq": v.train_freq,
    "gradient_steps": v.integer(1, allowed=(-1,)),
    "n_steps": v.integer(1),
    "policy_delay": v.integer(1),
    "target_policy_noise": v.real(0.0),
    "target_noise_clip": v.real(0.0),
    "target_greedy_mix": v.checked_by(check_target_greedy_mix, v.real()),
    "actor_greedy_weight": v.checked_by(check_actor_greedy_weight, v.real()),
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

    :param algorithm_class: The algorithm
    :param adc_keys: Whether ADC's policy options are accepted
    """
    if adc_keys:
        return dict(ADC_POLICY_KEYS)
    mlp_policy = getattr(algorithm_class, "policy_aliases", {}).get("MlpPolicy")
    if isinstance(mlp_policy, type) and issubclass(mlp_policy, ActorAverageTD3Policy):
        return {"actor_average_tau": ADC_POLICY_KEYS["actor_average_tau"]}
    return {}
