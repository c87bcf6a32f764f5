"""
An averaged actor for SB3's TD3 family (ADC, TD3, DDPG): the deployed policy as a Polyak average of the actor's iterates.

Not in the ADC paper. A deterministic actor trained with the policy gradient can swing between checkpoints: on the
lidar obstacle course a run's validation success moved from 0.96 to 0.56 and back within 30,000 steps (docs, critic
study). Averaging the iterates (Polyak-Ruppert averaging) gives a deployed policy that follows the actor's trend
without its last swing, while exploration and learning keep using the actor itself.

:class:`ActorAverageTD3Policy` holds the average and chooses which actor predicts; the algorithm tells it after
its actor updates (:meth:`ActorAverageTD3Policy.update_actor_average`): ADC after every actor update,
:class:`TD3WithActorAverage` (SB3's ``TD3.train`` has no hook per actor update) after every call of ``train``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, FlattenExtractor
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.td3.policies import Actor, CnnPolicy, MultiInputPolicy, TD3Policy
from stable_baselines3.td3.td3 import TD3
from torch import nn

from sb3_adc.common.fast_update import foreach_polyak_update


def check_actor_average_tau(actor_average_tau: object) -> None:
    """
    Raise ``ValueError`` unless ``actor_average_tau`` is a number in ``[0, 1)``: the weight of each new actor in
    :class:`ActorAverageTD3Policy`'s averaged actor, 0 for no average.

    :param actor_average_tau: The averaging coefficient
    """
    tau = actor_average_tau
    if isinstance(tau, bool) or not isinstance(tau, (int, float)) or not 0 <= tau < 1:
        raise ValueError(
            "`actor_average_tau` must be a number >= 0 and < 1 (0: no averaged actor; 1e-4 averages over about "
            f"10,000 actor updates), got {actor_average_tau!r}."
        )


def actor_average_weight(actor_average_tau: float, n_actor_updates: int, n_new: int = 1) -> float:
    """
    The weight of the newest actor in the average after the ``n_actor_updates``-th actor update, when it stands for
    the last ``n_new`` updates: ``max(1 - (1 - tau) ** n_new, n_new / n_actor_updates)``, ``max(tau, 1 / n)`` for
    one update (the plain mean of the iterates for the first ``1 / tau`` updates, an exponential moving average
    after).

    :param actor_average_tau: The averaging coefficient (in ``(0, 1)``)
    :param n_actor_updates: Actor updates since training began, the newest included (at least ``n_new``)
    :param n_new: Actor updates the newest actor stands for
    """
    if not 1 <= n_new <= n_actor_updates:
        raise ValueError(f"`n_new` must be between 1 and `n_actor_updates` ({n_actor_updates}), got {n_new}.")
    # One update: exactly ``tau`` (``1 - (1 - tau)`` differs from ``tau`` in the last bits).
    exponential = actor_average_tau if n_new == 1 else 1.0 - (1.0 - actor_average_tau) ** n_new
    return max(exponential, n_new / n_actor_updates)


class ActorAverageTD3Policy(TD3Policy):
    """
    SB3's TD3 policy (actor, critics and their targets), optionally with an averaged actor for deployment.

    :param observation_space: Observation space
    :param action_space: Action space
    :param lr_schedule: Learning rate schedule (could be constant)
    :param net_arch: The specification of the policy and value networks.
    :param activation_fn: Activation function
    :param features_extractor_class: Features extractor to use.
    :param features_extractor_kwargs: Keyword arguments to pass to the features extractor.
    :param normalize_images: Whether to normalize images or not, dividing by 255.0 (True by default)
    :param optimizer_class: The optimizer to use, ``th.optim.Adam`` by default
    :param optimizer_kwargs: Additional keyword arguments, excluding the learning rate, to pass to the optimizer
    :param n_critics: Number of critic networks to create.
    :param share_features_extractor: Whether to share or not the features extractor between the actor and the
        critic (this saves computation time)
    :param actor_average_tau: Not in the ADC paper: with a value in ``(0, 1)``, the policy keeps ``actor_average``,
        a Polyak average of the actor's iterates (after the ``n``-th actor update, ``average <- (1 - t) average +
        t actor`` with ``t = max(actor_average_tau, 1 / n)``: their plain mean for the first
        ``1 / actor_average_tau`` updates, an exponential moving average after). Deterministic predictions (the
        deployed policy: evaluation, ``EvalCallback``) use the average; ``predict(deterministic=False)`` and the
        exploration during training use the actor itself, so the average does not change what is learned.
        0 (default): no average, SB3's ``TD3Policy``
    """

    actor_average: Actor | None

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        lr_schedule: Schedule,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        features_extractor_class: type[BaseFeaturesExtractor] = FlattenExtractor,
        features_extractor_kwargs: dict[str, Any] | None = None,
        normalize_images: bool = True,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        n_critics: int = 2,
        share_features_extractor: bool = False,
        actor_average_tau: float = 0.0,
    ):
        check_actor_average_tau(actor_average_tau)
        # TD3Policy.__init__ builds the networks, the average among them.
        self.actor_average_tau = float(actor_average_tau)
        super().__init__(
            observation_space,
            action_space,
            lr_schedule,
            net_arch=net_arch,
            activation_fn=activation_fn,
            features_extractor_class=features_extractor_class,
            features_extractor_kwargs=features_extractor_kwargs,
            normalize_images=normalize_images,
            optimizer_class=optimizer_class,
            optimizer_kwargs=optimizer_kwargs,
            n_critics=n_critics,
            share_features_extractor=share_features_extractor,
        )

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(actor_average_tau=self.actor_average_tau)
        return data

    def _build(self, lr_schedule: Schedule) -> None:
        super()._build(lr_schedule)
        self.actor_average = None
        # The parameter lists of the update, gathered once rather than at every actor update (a training hot path).
        self._average_parameters: tuple[list[nn.Parameter], list[nn.Parameter]] | None = None
        if self.actor_average_tau > 0:
            # Initialised without drawing from torch's generator, so that a seeded run learns exactly what it
            # would without the average.
            with th.random.fork_rng(devices=[]):
                self.actor_average = self.make_actor(features_extractor=None)
            self.actor_average.load_state_dict(self.actor.state_dict())
            self.actor_average.set_training_mode(False)
            self._average_parameters = (list(self.actor.parameters()), list(self.actor_average.parameters()))

    def set_training_mode(self, mode: bool) -> None:
        """
        SB3's ``TD3Policy.set_training_mode`` (the actor and the critics; the targets and the average stay in
        evaluation mode), skipped when they are in that mode already: SB3 calls it three times per environment step
        (collecting, predicting, training), and ``nn.Module.train`` walks every submodule through
        ``nn.Module.__setattr__``, a noticeable share of a training step with small networks. When the mode does
        change, the flag is written straight into the submodules' ``__dict__`` (where ``nn.Module`` keeps it), unless
        one of them overrides ``train``.

        :param mode: Training mode (``True``) or evaluation mode
        """
        if self.training == mode and self.actor.training == mode and self.critic.training == mode:
            return
        cached = self.__dict__.get("_mode_modules")
        if cached is None or cached[0] is not self.actor or cached[1] is not self.critic:
            modules = [*self.actor.modules(), *self.critic.modules()]
            plain = all(type(module).train is nn.Module.train for module in modules)
            cached = (self.actor, self.critic, modules if plain else None)
            # Not an attribute of the module tree (a list, not a Module): state dict and pickling are unchanged.
            self.__dict__["_mode_modules"] = cached
        if cached[2] is None:
            super().set_training_mode(mode)
            return
        for module in cached[2]:
            module.__dict__["training"] = mode
        self.training = mode

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        if deterministic and self.actor_average is not None:
            return self.actor_average(observation)
        return self.actor(observation)

    def update_actor_average(self, n_actor_updates: int, n_new: int = 1, foreach: bool = False) -> None:
        """
        Move the averaged actor towards the actor after an actor update, by :func:`actor_average_weight` (nothing
        without an average).

        :param n_actor_updates: Actor updates since training began, the newest included (the count is saved with
            the model, so that a resumed run goes on with the same weights)
        :param n_new: Actor updates since the last call
        :param foreach: Update all the tensors in one call (:func:`~sb3_adc.common.fast_update.foreach_polyak_update`,
            the same update up to float rounding) rather than with SB3's ``polyak_update``
        """
        if self._average_parameters is None:
            return
        weight = actor_average_weight(self.actor_average_tau, n_actor_updates, n_new)
        if foreach:
            foreach_polyak_update(*self._average_parameters, weight)
        else:
            polyak_update(*self._average_parameters, weight)

    def drop_actor_average(self) -> bool:
        """
        Deploy the actor itself from now on (deterministic predictions then use the actor, as without
        ``actor_average_tau``): to score the same run's actor beside its average.

        :return: Whether there was an average to drop
        """
        had_average = self.actor_average is not None
        self.actor_average = None
        self._average_parameters = None
        return had_average


class TD3WithActorAverage(TD3):
    """
    TD3 (or a subclass) that keeps its :class:`ActorAverageTD3Policy`'s averaged actor up to date.

    SB3's ``TD3.train`` updates the actor every ``policy_delay`` gradient steps and has no hook per actor update, so
    the average is moved once after each call of :meth:`train` that updated the actor, towards the actor at the end
    of the call, with the weight of the actor updates the call made (:func:`actor_average_weight`). With one
    gradient step per call (``train_freq=1, gradient_steps=1``, the lidar settings) this is the average of every
    actor iterate, the rule ADC follows. Policies without an average (``actor_average_tau=0``, or SB3's
    ``TD3Policy`` of a model file saved by SB3) train as SB3's TD3, update for update. Its ``MlpPolicy`` is
    :class:`ActorAverageTD3Policy`.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": ActorAverageTD3Policy,
        "CnnPolicy": CnnPolicy,
        "MultiInputPolicy": MultiInputPolicy,
    }

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        n_before = self._n_updates // self.policy_delay
        super().train(gradient_steps, batch_size)
        n_after = self._n_updates // self.policy_delay
        if isinstance(self.policy, ActorAverageTD3Policy) and n_after > n_before:
            self.policy.update_actor_average(n_after, n_new=n_after - n_before)
