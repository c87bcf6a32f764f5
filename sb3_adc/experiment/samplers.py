"""
Optuna search spaces of the algorithms that ``sb3-adc train -optimize`` tunes.

Each sampler draws hyperparameters from an Optuna trial and returns them as overrides of the algorithm's entry
(the same ``key: value`` pairs as ``-params``), so a trial runs through the same engine, validation and log
layout as any other run. The spaces follow the RL Zoo's ``rl_zoo3/hyperparams_opt.py`` for the keys the
algorithms share. :func:`register_zoo_samplers` also adds them to the Zoo's ``HYPERPARAMS_SAMPLER`` (for the names
the Zoo lacks), so that the Zoo's own ``objective`` searches ADC's space: the values drawn are validated as an entry
and returned as constructor keywords. ``sb3-adc train -optimize`` keeps its own objective, because a trial there
trains several seeds through our engine where the Zoo's trains one.

ADC and DDPG are searched over the same shared keys, including the critic-to-actor learning-rate ratio and the
epsilon-gated exploration schedule; ADC also over its own knobs: the critic design, the number of intervals
and, for the Legendre critic, the degree of the basis. TD3 and SAC get the shared keys their constructors take.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from typing import Any

import optuna

#: Network sizes tried for the actor and critic (the RL Zoo's names and sizes).
NET_ARCHS: dict[str, list[int]] = {"small": [64, 64], "medium": [256, 256], "big": [400, 300]}

Sampler = Callable[["Space"], dict[str, Any]]
#: A key's range: a list of choices (categorical), or ``("log" | "uniform", low, high)`` (a float).
Ranges = Mapping[str, "list[Any] | tuple[str, float, float]"]

GAMMAS = [0.9, 0.95, 0.98, 0.99]
#: Keys of every off-policy actor-critic here: discount, learning rate, batch, soft update, start.
SHARED_OFF_POLICY: Ranges = {
    "gamma": GAMMAS,
    "learning_rate": ("log", 1e-4, 3e-3),
    "batch_size": [64, 128, 256],
    "tau": [0.005, 0.01, 0.02],
    "learning_starts": [1000, 5000, 10000],
}
#: Gaussian exploration, always on or epsilon-gated (the ADC paper's), and the epsilon decay schedule.
EXPLORATION: Ranges = {"noise_type": ["normal", "epsilon-normal"], "noise_std": [0.05, 0.1, 0.2, 0.3, 0.5]}
EPSILON_SCHEDULE: Ranges = {"epsilon_decay_steps": [5000, 10000, 20000, 40000], "epsilon_final": [0.0, 0.05, 0.1, 0.2]}
#: The dueling DQN over discretised actions: the RL Zoo's DQN space without the network (its policy is ours).
DQN: Ranges = {
    "gamma": GAMMAS,
    "learning_rate": ("log", 1e-5, 3e-3),
    "batch_size": [32, 64, 128, 256],
    "buffer_size": [5000, 50000, 200000],
    "exploration_fraction": ("uniform", 0.05, 0.5),
    "exploration_final_eps": ("uniform", 0.0, 0.2),
    "target_update_interval": [1, 100, 1000],
    "learning_starts": [0, 1000, 5000],
}


class Space:
    """
    A trial's view of the search: suggestions for the keys that the command line does not fix.

    :param trial: The Optuna trial
    :param entry: The entry the trial starts from (the shipped one, with the fixed overrides)
    :param fixed: Keys fixed by ``-params``: never searched, so that a trial's parameters are what it ran
    :param listed: Choices given for keys (``--search-space``): such a key is drawn from its choices, whether the
        algorithm's space searches it (its own range is then replaced) or not (it is added to the search); the
        values drawn are :attr:`drawn`
    """

    def __init__(
        self,
        trial: optuna.Trial,
        entry: Mapping[str, Any],
        fixed: Collection[str] = (),
        listed: Mapping[str, Sequence[Any]] | None = None,
    ):
        self.trial = trial
        self.fixed = frozenset(fixed)
        self.listed = dict(listed or {})
        #: The listed keys' values, drawn first so that the algorithm's space sees them in :attr:`entry` (the
        #: exploration schedule is searched only where the noise drawn is epsilon-gated, say).
        self.drawn: dict[str, Any] = {}
        for key, choices in self.listed.items():
            if all(choice is None or isinstance(choice, (bool, int, float, str)) for choice in choices):
                self.drawn[key] = trial.suggest_categorical(key, list(choices))
            else:
                # Optuna's categorical choices are scalars: other values (``env_wrapper`` lists, say) by index.
                self.drawn[key] = choices[trial.suggest_categorical(f"{key}_choice", list(range(len(choices))))]
        self.entry = {**entry, **self.drawn}

    def searches(self, key: str) -> bool:
        """Whether the algorithm's own space draws ``key``: neither fixed nor listed."""
        return key not in self.fixed and key not in self.listed

    def draw(self, params: dict[str, Any], ranges: Ranges) -> dict[str, Any]:
        """
        Draw into ``params`` (and return it) each key of ``ranges`` that the space searches, in their order.

        :param params: The trial's values so far
        :param ranges: The keys' ranges
        """
        for key, choices in ranges.items():
            if not self.searches(key):
                continue
            if isinstance(choices, tuple):
                scale, low, high = choices
                params[key] = self.trial.suggest_float(key, low, high, log=scale == "log")
            else:
                params[key] = self.trial.suggest_categorical(key, list(choices))
        return params

    def current(self, params: Mapping[str, Any], key: str, default: Any = None) -> Any:
        """The value of ``key`` drawn so far, else the entry's."""
        return params.get(key, self.entry.get(key, default))


def _shared_off_policy(space: Space) -> dict[str, Any]:
    """:data:`SHARED_OFF_POLICY`, and the network where the entry's ``policy_kwargs`` set nothing else."""
    params = space.draw({}, SHARED_OFF_POLICY)
    if _only_net_arch(space.entry.get("policy_kwargs")) and space.searches("policy_kwargs"):
        params["policy_kwargs"] = {"net_arch": NET_ARCHS[space.trial.suggest_categorical("net_arch", list(NET_ARCHS))]}
    return params


def _only_net_arch(policy_kwargs: Any) -> bool:
    """Whether an entry's ``policy_kwargs`` set nothing but ``net_arch`` (replacing them then loses nothing)."""
    if policy_kwargs is None:
        return True
    if isinstance(policy_kwargs, Mapping):
        return set(policy_kwargs) <= {"net_arch"}
    text = str(policy_kwargs).replace(" ", "")
    return text.startswith("dict(net_arch=") and text.count("=") == 1


def _exploration(space: Space, params: dict[str, Any]) -> dict[str, Any]:
    """:data:`EXPLORATION`, and :data:`EPSILON_SCHEDULE` where the noise is epsilon-gated."""
    space.draw(params, EXPLORATION)
    if space.current(params, "noise_type") == "epsilon-normal":
        space.draw(params, EPSILON_SCHEDULE)
    return params


def _critic_rate(space: Space, params: dict[str, Any]) -> dict[str, Any]:
    """The critic's learning rate as a multiple of the actor's (the paper uses twice the actor's)."""
    if space.searches("critic_learning_rate"):
        ratio = space.trial.suggest_categorical("critic_rate_ratio", [1.0, 2.0, 5.0])
        params["critic_learning_rate"] = float(space.current(params, "learning_rate", 1e-3)) * ratio
    return params


def sample_ddpg(space: Space) -> dict[str, Any]:
    """
    DDPG (with a critic learning rate of its own): the shared keys, the critic-rate ratio and the exploration.

    :param space: The trial's search space
    """
    return _exploration(space, _critic_rate(space, _shared_off_policy(space)))


def sample_adc(space: Space) -> dict[str, Any]:
    """
    ADC: DDPG's space, plus the critic design, the number of intervals and the Legendre basis degree.

    :param space: The trial's search space
    """
    params = space.draw(sample_ddpg(space), {"critic_design": ["legendre", "state_value", "paper"]})
    space.draw(params, {"n_intervals": [20, 50, 100, 200]})
    if space.current(params, "critic_design", "legendre") == "legendre":
        space.draw(params, {"basis_degree": [2, 4, 6]})
    return params


def sample_td3(space: Space) -> dict[str, Any]:
    """
    TD3: the shared keys and the exploration noise (its twin critics, delay and smoothing stay SB3's).

    :param space: The trial's search space
    """
    return _exploration(space, _shared_off_policy(space))


def sample_sac(space: Space) -> dict[str, Any]:
    """
    SAC: the shared keys and the entropy coefficient (learned, or fixed).

    :param space: The trial's search space
    """
    return space.draw(_shared_off_policy(space), {"ent_coef": ["auto", 0.1, 0.01]})


def sample_vanilla_ac(space: Space) -> dict[str, Any]:
    """
    The vanilla actor-critic (no replay, no target networks): discount, rates and exploration.

    :param space: The trial's search space
    """
    params = space.draw({}, {"gamma": GAMMAS, "learning_rate": ("log", 1e-5, 3e-3)})
    return _exploration(space, _critic_rate(space, params))


def sample_dqn(space: Space) -> dict[str, Any]:
    """
    The dueling DQN (:data:`DQN`).

    :param space: The trial's search space
    """
    return space.draw({}, DQN)


#: ``--algo`` name -> its search space.
SAMPLERS: dict[str, Sampler] = {
    "adc": sample_adc,
    "ddpg": sample_ddpg,
    "td3": sample_td3,
    "sac": sample_sac,
    "vanilla_ac": sample_vanilla_ac,
    "dqn": sample_dqn,
}


def sample(algo: str, space: Space) -> dict[str, Any]:
    """
    A trial's values: the algorithm's space, with the listed keys drawn from their choices.

    :param algo: The algorithm (a key of :data:`SAMPLERS`)
    :param space: The trial's search space
    """
    return {**SAMPLERS[algo](space), **space.drawn}


def zoo_sampler(algo: str) -> Callable[[optuna.Trial, int, int, dict[str, Any]], dict[str, Any]]:
    """
    The space of ``algo`` with the signature of the Zoo's samplers (``trial, n_actions, n_envs, additional_args``):
    the values drawn go through the same validation as a hyperparameter entry, and come back as the constructor
    keywords the Zoo's ``objective`` passes to the algorithm (``action_noise`` built for ``n_actions``).

    :param algo: The algorithm (a key of :data:`SAMPLERS`)
    """
    from gymnasium import spaces

    from sb3_adc.config.loader import resolve_entry

    def sampler(trial: optuna.Trial, n_actions: int, n_envs: int, additional_args: dict[str, Any]) -> dict[str, Any]:
        values = sample(algo, Space(trial, {}))
        config = resolve_entry(algo, "zoo", {"policy": "MlpPolicy", "n_timesteps": 1, **values}, f"{algo} sampler")
        kwargs = {key: value for key, value in config.model_kwargs.items() if key != "policy"}
        if config.noise is not None:
            kwargs["action_noise"] = config.noise.build(spaces.Box(-1.0, 1.0, (n_actions,)))
        return kwargs

    return sampler


def register_zoo_samplers() -> None:
    """Add :func:`zoo_sampler` of each algorithm of :data:`SAMPLERS` that the Zoo's ``HYPERPARAMS_SAMPLER`` lacks
    (``adc``, ``vanilla_ac``); the Zoo's own spaces stay for its algorithms."""
    from rl_zoo3.hyperparams_opt import HYPERPARAMS_SAMPLER

    for algo in SAMPLERS:
        HYPERPARAMS_SAMPLER.setdefault(algo, zoo_sampler(algo))  # type: ignore[arg-type]  # typed as its first entry


__all__ = ["NET_ARCHS", "SAMPLERS", "Sampler", "Space", "register_zoo_samplers", "sample", "zoo_sampler"]
