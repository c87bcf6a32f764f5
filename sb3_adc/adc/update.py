"""
ADC's gradient steps (Algorithm 1, lines 9-14): the TD targets with the greedy value, the critic and actor losses with
the greedy pull, the soft target updates, and the fast path of ``fast_update``.
"""

from __future__ import annotations

import numpy as np
import torch as th
from stable_baselines3.common.type_aliases import PyTorchObs, ReplayBufferSamples
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.td3.td3 import TD3
from torch.nn import functional as F

from sb3_adc.adc.policies import ADCPolicy, DuelingIntervalCritic
from sb3_adc.adc.stacked import StackedCritics, stackable
from sb3_adc.common.fast_update import FusedAdamStep, foreach_polyak_update, select_optimizer_implementation


class ADCUpdate(TD3):
    """
    TD3's ``train`` with ADC's targets (:meth:`target_q_values`) and actor loss (:meth:`actor_loss`), for
    :class:`~sb3_adc.ADC`, which sets ``target_greedy_mix``, ``actor_greedy_weight`` and ``fast_update``.
    """

    policy: ADCPolicy
    critic: DuelingIntervalCritic  # type: ignore[assignment]
    critic_target: DuelingIntervalCritic  # type: ignore[assignment]
    target_greedy_mix: float
    actor_greedy_weight: float
    fast_update: bool
    #: The last training batch, kept for the logged diagnostics only (see ``ADC.dump_logs``).
    _last_batch: tuple[PyTorchObs, th.Tensor] | None = None

    def _setup_model(self) -> None:
        super()._setup_model()
        # Parameter lists of the per-step updates, gathered once rather than at every gradient step.
        self._actor_parameters = list(self.actor.parameters())
        self._target_updates = [
            (list(self.critic.parameters()), list(self.critic_target.parameters())),
            (self._actor_parameters, list(self.actor_target.parameters())),
        ]
        # The fast path's batched twin critics, online and target (see `_link_stacked_critics`).
        self._stacked_critics: tuple[StackedCritics, StackedCritics] | None = None
        self._stacked_for: tuple[DuelingIntervalCritic, DuelingIntervalCritic] | None = None
        # The fast path's optimizer steps, actor's and critic's (see `_fast_steps`).
        self._fused_steps: tuple[FusedAdamStep, FusedAdamStep] | None = None

    def _link_stacked_critics(self) -> tuple[StackedCritics, StackedCritics] | None:
        """
        The fast path's batched online and target critics, for a critic design that allows them (:func:`stackable`),
        built or re-linked to the critics' parameters when needed (a loaded or moved policy); ``None`` otherwise.
        """
        # Decided once per pair of critics (`stackable` walks every module: a tenth of a step on the lidar entry's nets).
        critics = (self.critic, self.critic_target)
        if self._stacked_for != critics:
            self._stacked_for = critics
            self._stacked_critics = None
            if stackable(self.critic):
                self._stacked_critics = (StackedCritics(self.critic, True), StackedCritics(self.critic_target, False))
        for stacked in self._stacked_critics or ():
            stacked.link()
        return self._stacked_critics

    def _fast_steps(self) -> tuple[FusedAdamStep, FusedAdamStep]:
        """The fast path's steps of the actor's and the critic's optimizers (rebuilt for replaced optimizers)."""
        steps = self._fused_steps
        if steps is None or steps[0].optimizer is not self.actor.optimizer or steps[1].optimizer is not self.critic.optimizer:
            steps = self._fused_steps = (FusedAdamStep(self.actor.optimizer), FusedAdamStep(self.critic.optimizer))
        return steps

    def _q_values(self, target: bool, observations: PyTorchObs, actions: th.Tensor) -> th.Tensor:
        """
        ``Q_i(s, a)`` of every critic network, online or target: in one batched pass on the fast path where the
        critic design allows it, otherwise one network after the other.

        :param target: Whether to evaluate the target critic
        :param observations: Observations
        :param actions: Scaled actions ``(batch, action_dim)``
        :return: ``(n_critics, batch, 1)``
        """
        stacked = self._stacked_critics
        if self.fast_update and stacked is not None and stacked[0].critic is self.critic and stacked[0].is_current():
            return stacked[int(target)].q_values(observations, actions)  # type: ignore[arg-type]
        critic = self.critic_target if target else self.critic
        return th.stack(critic(observations, actions))

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        """
        TD3's ``train`` with ADC's targets and actor loss, and, with ``fast_update``, the fast path: what differs
        from TD3's loop is marked ``fast``. Parameters as TD3's.

        :param gradient_steps: Number of gradient steps
        :param batch_size: Minibatch size of each step
        """
        # Switch to train mode (this affects batch norm / dropout)
        self.policy.set_training_mode(True)
        optimizers = [self.actor.optimizer, self.critic.optimizer]
        self._update_learning_rate(optimizers)
        fast = self.fast_update
        select_optimizer_implementation(optimizers, fast)
        # fast: the batched twin critics, and one Polyak update over every target parameter (the stacked critics')
        stacked = self._link_stacked_critics() if fast else None
        # fast: the fused Adam kernel on tensor lists gathered once (`optimizer.step()` for other optimizers)
        actor_step, critic_step = self._fast_steps() if fast else (None, None)
        if stacked is not None:
            sources, targets = [*stacked[0].stacked, *self._actor_parameters], [*stacked[1].stacked]
            targets += self._target_updates[1][1]
        else:
            sources = [*self._target_updates[0][0], *self._target_updates[1][0]]
            targets = [*self._target_updates[0][1], *self._target_updates[1][1]]

        # fast: the losses stay tensors, read once after the loop (`.item()` at each step waits for the device).
        actor_losses: list[th.Tensor | float] = []
        critic_losses: list[th.Tensor | float] = []
        for _ in range(gradient_steps):
            self._n_updates += 1
            replay_data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)  # type: ignore[union-attr]
            # Algorithm 1, lines 9-11 (with the greedy value when target_greedy_mix > 0)
            target_q_values = self.target_q_values(replay_data)

            # Line 12: minimise the squared TD error of every dueling critic network
            current_q_values = self._q_values(False, replay_data.observations, replay_data.actions)
            if fast:
                # The sum over the critics of each one's mean squared error.
                critic_loss = F.mse_loss(current_q_values, target_q_values.expand_as(current_q_values))
                critic_loss = critic_loss * current_q_values.shape[0]
                critic_losses.append(critic_loss.detach())
            else:
                critic_loss = sum(F.mse_loss(current_q, target_q_values) for current_q in current_q_values)  # type: ignore[assignment]
                critic_losses.append(critic_loss.item())

            if stacked is not None:
                # fast: zeroed in place, the per-critic gradients being views of the stacked ones
                stacked[0].zero_grad()
            elif critic_step is not None:
                critic_step.zero_grad()
            else:
                self.critic.optimizer.zero_grad()
            critic_loss.backward()
            if critic_step is not None:
                critic_step.step()
            else:
                self.critic.optimizer.step()

            if self._n_updates % self.policy_delay == 0:
                # Line 13: deterministic policy gradient through the dueling critic (and the greedy pull, if any)
                actor_loss = self.actor_loss(replay_data.observations)
                actor_losses.append(actor_loss.detach() if fast else actor_loss.item())

                # Only the actor's gradients are needed: autograd skips the critic's weight gradients.
                if actor_step is not None:
                    actor_step.zero_grad()
                    actor_loss.backward(inputs=self._actor_parameters)
                    actor_step.step()
                else:
                    self.actor.optimizer.zero_grad()
                    actor_loss.backward(inputs=self._actor_parameters)
                    self.actor.optimizer.step()

                # Line 14: soft target updates
                if fast:
                    foreach_polyak_update(sources, targets, self.tau)
                else:
                    for parameters, target_parameters in self._target_updates:
                        polyak_update(parameters, target_parameters, self.tau)
                # Copy running stats, see SB3 GH issue #996
                polyak_update(self.critic_batch_norm_stats, self.critic_batch_norm_stats_target, 1.0)
                polyak_update(self.actor_batch_norm_stats, self.actor_batch_norm_stats_target, 1.0)
                # The deployed policy's average of the actor's iterates (``actor_average_tau``; none by default).
                self.policy.update_actor_average(self._n_updates // self.policy_delay, foreach=fast)

        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if len(actor_losses) > 0:
            self.logger.record("train/actor_loss", _mean(actor_losses))
        if len(critic_losses) > 0:
            self.logger.record("train/critic_loss", _mean(critic_losses))
        if gradient_steps > 0:
            # The critic's streams on this batch are computed only when the logs are written (see `dump_logs`).
            self._last_batch = (replay_data.observations, replay_data.actions)

    def target_q_values(self, replay_data: ReplayBufferSamples) -> th.Tensor:
        """
        The TD targets of a batch (Algorithm 1, lines 9-11), without gradient: ``y = r + gamma (1 - done) Q_next``
        with the paper's ``Q_next = Q'(s', mu'(s'))`` (TD3's smoothing noise added to ``mu'(s')`` when
        ``target_policy_noise > 0``, and the minimum over the target critics when there are several), mixed with the
        greedy value when ``target_greedy_mix = m > 0``::

            Q_next = (1 - m) Q'(s', mu'(s') [+ noise]) + m min_i Q'_i(s', z*),   z* = argmax_z Q_1(s', z)

        ``z*`` is the best point of the grid of interval centres for the first *online* critic
        (:meth:`~sb3_adc.adc.policies.DuelingIntervalCritic.greedy_action`), valued by the *target* critics.

        :param replay_data: A batch of transitions; ``discounts`` (n-step replay) replace ``gamma`` when set
        :return: ``(batch, 1)``
        """
        # For n-step replay, discount factor is gamma**n_steps (when no early termination)
        discounts = replay_data.discounts if replay_data.discounts is not None else self.gamma
        next_observations = replay_data.next_observations
        mix = self.target_greedy_mix
        with th.no_grad():
            if mix < 1:
                next_actions = self.actor_target(next_observations)
                if self.target_policy_noise > 0:
                    noise = next_actions.clone().normal_(0, self.target_policy_noise)
                    noise = noise.clamp(-self.target_noise_clip, self.target_noise_clip)
                    next_actions = (next_actions + noise).clamp(-1, 1)
                next_q_value = _min_over_critics(self._q_values(True, next_observations, next_actions))
            if mix > 0:
                greedy_actions, _ = self.critic.greedy_action(next_observations)
                greedy_q_value = _min_over_critics(self._q_values(True, next_observations, greedy_actions))
                next_q_value = greedy_q_value if mix == 1 else (1 - mix) * next_q_value + mix * greedy_q_value
            return replay_data.rewards + (1 - replay_data.dones) * discounts * next_q_value

    def actor_loss(self, observations: th.Tensor) -> th.Tensor:
        """
        The actor loss of a batch (Algorithm 1, line 13; Eq. 15): ``-mean_s Q_1(s, mu(s))``, the deterministic policy
        gradient through the first critic, plus, when ``actor_greedy_weight = w > 0``, the greedy policy-improvement
        term ``w mean_s 1[Q_1(s, z*) > Q_1(s, mu(s))] ||mu(s) - z*(s)||^2`` with ``z* = argmax_z Q_1(s, z)`` over the
        grid of interval centres (a constant: the critic gets no gradient from this term).

        :param observations: Observations
        :return: a scalar, with gradients for the actor (and, through ``Q_1(s, mu(s))``, the critic's weights, which
            :meth:`train` leaves out)
        """
        actions = self.actor(observations)
        q_values = self.critic.q1_forward(observations, actions)
        loss = -q_values.mean()
        if self.actor_greedy_weight > 0:
            greedy_actions, greedy_q_values = self.critic.greedy_action(observations)
            improves = greedy_q_values > q_values.detach()
            pull = (actions - greedy_actions).square().sum(dim=1, keepdim=True)
            loss = loss + self.actor_greedy_weight * th.where(improves, pull, 0.0).mean()
        return loss

    def _excluded_save_params(self) -> list[str]:
        # The last training batch is kept for the logged diagnostics only; the parameter lists are the policy's.
        excluded = [
            "_last_batch",
            "_actor_parameters",
            "_target_updates",
            "_stacked_critics",
            "_stacked_for",
            "_fused_steps",
        ]
        return [*super()._excluded_save_params(), *excluded]


def _min_over_critics(q_values: th.Tensor) -> th.Tensor:
    """Clipped double-Q: the minimum over the critics' values ``(n_critics, batch, 1)`` (the value itself for a single
    critic), ``(batch, 1)``."""
    return q_values[0] if q_values.shape[0] == 1 else q_values.amin(0)


def _mean(losses: list[th.Tensor | float]) -> float:
    """The mean of a ``train`` call's losses: floats (plain path) or tensors, read from the device once (fast path)."""
    tensors = [loss for loss in losses if isinstance(loss, th.Tensor)]
    if tensors:
        return th.stack(tensors).mean().item()
    return float(np.mean([float(loss) for loss in losses]))
