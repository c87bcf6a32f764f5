"""
Optuna search spaces of the algorithms that ``sb3-adc train -optimize`` tunes: a sampler draws overrides of the
algorithm's entry (as ``-params``) from a trial, so a trial runs through the same engine as any run. The shared keys
follow the RL Zoo's ``hyperparams_opt.py``; :func:`register_zoo_samplers` adds the spaces the Zoo lacks to its
``HYPERPARAMS_SAMPLER``.
"""

from __future__ import annotations

import functools
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
    :param listed: Choices given for keys (``--search-space``): such a key is drawn from its choices (replacing the
        algorithm's range, or added to the search); the values drawn are :attr:`drawn`
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
        #: The listed keys' values, drawn first so that the algorithm's space sees them in :attr:`entry`.
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
            if isinstance(choices, tuple) and self.searches(key):
                params[key] = self.trial.suggest_float(key, choices[1], choices[2], log=choices[0] == "log")
            elif self.searches(key):
                params[key] = self.trial.suggest_categorical(key, list(choices))
        return params

    def current(self, params: Mapping[str, Any], key: str, default: Any = None) -> Any:
        """The value of ``key`` drawn so far, else the entry's."""
        return params.get(key, self.entry.get(key, default))


def _net_arch(space: Space, params: dict[str, Any]) -> None:
    """The network, where the entry's ``policy_kwargs`` set nothing but ``net_arch`` (replacing them loses nothing)."""
    policy_kwargs = space.entry.get("policy_kwargs")
    text = str(policy_kwargs).replace(" ", "")
    only_net_arch = policy_kwargs is None or (
        set(policy_kwargs) <= {"net_arch"}
        if isinstance(policy_kwargs, Mapping)
        else text.startswith("dict(net_arch=") and text.count("=") == 1
    )
    if only_net_arch and space.searches("policy_kwargs"):
        params["policy_kwargs"] = {"net_arch": NET_ARCHS[space.trial.suggest_categorical("net_arch", list(NET_ARCHS))]}


def _critic_rate(space: Space, params: dict[str, Any]) -> None:
    """The critic's learning rate as a multiple of the actor's (the paper uses twice the actor's)."""
    if space.searches("critic_learning_rate"):
        ratio = space.trial.suggest_categorical("critic_rate_ratio", [1.0, 2.0, 5.0])
        params["critic_learning_rate"] = float(space.current(params, "learning_rate", 1e-3)) * ratio


#: A step of a space: ranges drawn, a function drawing into the values, or ``(ranges, key, value, default)``:
#: ranges drawn where ``key`` (drawn so far, else the entry's, else ``default``) is ``value``.
Step = Ranges | Callable[[Space, dict[str, Any]], None] | tuple[Ranges, str, Any, Any]
EPSILON_GATED: Step = (EPSILON_SCHEDULE, "noise_type", "epsilon-normal", None)
DDPG: tuple[Step, ...] = (SHARED_OFF_POLICY, _net_arch, _critic_rate, EXPLORATION, EPSILON_GATED)
#: ``--algo`` name -> the steps of its search space, in the order they are drawn: DDPG (with a critic learning rate
#: of its own); ADC, DDPG's plus its critic design, intervals and Legendre basis degree; TD3 (its twin critics,
#: delay and smoothing stay SB3's); SAC with its entropy coefficient; the vanilla actor-critic (no replay, no target
#: networks); the dueling DQN.
SPACES: dict[str, tuple[Step, ...]] = {
    "adc": (
        *DDPG,
        {"critic_design": ["legendre", "state_value", "paper"], "n_intervals": [20, 50, 100, 200]},
        ({"basis_degree": [2, 4, 6]}, "critic_design", "legendre", "legendre"),
    ),
    "ddpg": DDPG,
    "td3": (SHARED_OFF_POLICY, _net_arch, EXPLORATION, EPSILON_GATED),
    "sac": (SHARED_OFF_POLICY, _net_arch, {"ent_coef": ["auto", 0.1, 0.01]}),
    "vanilla_ac": ({"gamma": GAMMAS, "learning_rate": ("log", 1e-5, 3e-3)}, _critic_rate, EXPLORATION, EPSILON_GATED),
    "dqn": (DQN,),
}


def _draw_steps(steps: tuple[Step, ...], space: Space) -> dict[str, Any]:
    """The values drawn by ``steps``, in order."""
    params: dict[str, Any] = {}
    for step in steps:
        if callable(step):
            step(space, params)
        elif isinstance(step, tuple):
            ranges, key, value, default = step
            if space.current(params, key, default) == value:
                space.draw(params, ranges)
        else:
            space.draw(params, step)
    return params


#: ``--algo`` name -> its search space.
SAMPLERS: dict[str, Sampler] = {algo: functools.partial(_draw_steps, steps) for algo, steps in SPACES.items()}


def sample(algo: str, space: Space) -> dict[str, Any]:
    """
    A trial's values: the algorithm's space, with the listed keys drawn from their choices.

    :param algo: The algorithm (a key of :data:`SAMPLERS`)
    :param space: The trial's search space
    """
    return {**SAMPLERS[algo](space), **space.drawn}


def zoo_sampler(algo: str) -> Callable[[optuna.Trial, int, int, dict[str, Any]], dict[str, Any]]:
    """
    The space of ``algo`` as a Zoo sampler (``trial, n_actions, n_envs, additional_args``): the values drawn are
    validated as an entry and returned as the algorithm's keywords (``action_noise`` built for ``n_actions``).

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
