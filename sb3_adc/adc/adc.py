from __future__ import annotations

import io
import pathlib
from functools import partial
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from stable_baselines3.common.base_class import maybe_make_env
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, PyTorchObs, ReplayBufferSamples, Schedule
from stable_baselines3.common.utils import polyak_update
from torch.nn import functional as F

from sb3_adc.adc.exploration import check_interval_exploration, check_interval_temperature, explore_from_advantages
from sb3_adc.adc.policies import (
    DEFAULT_CRITIC_DESIGN,
    GREEDY_CRITIC_DESIGNS,
    ADCPolicy,
    CnnPolicy,
    DuelingIntervalCritic,
    MlpPolicy,
    MultiInputPolicy,
)
from sb3_adc.adc.stacked import StackedCritics, stackable
from sb3_adc.common.critic_learning_rate import TD3WithCriticLearningRate
from sb3_adc.common.fast_update import FusedAdamStep, foreach_polyak_update, select_optimizer_implementation
from sb3_adc.common.model_files import CheckedModelFiles, model_file_error
from sb3_adc.common.noise import check_action_noise
from sb3_adc.common.schedules import ScaledSchedule
from sb3_adc.common.spaces import ActionSpaceError, check_action_space

SelfADC = TypeVar("SelfADC", bound="ADC")

#: Ratio of the critic's to the actor's learning rate in the ADC paper (Tables 1-3).
PAPER_CRITIC_LR_FACTOR = 2.0


def check_target_greedy_mix(target_greedy_mix: object) -> None:
    """
    Raise ``ValueError`` unless ``target_greedy_mix`` is a number in ``[0, 1]`` (see :class:`ADC`).

    :param target_greedy_mix: Share of the greedy value ``Q'(s', z*)`` in the TD target's next-state value
    """
    if (
        isinstance(target_greedy_mix, bool)
        or not isinstance(target_greedy_mix, (int, float))
        or not 0 <= target_greedy_mix <= 1
    ):
        raise ValueError(f"`target_greedy_mix` must be a number in [0, 1], got {target_greedy_mix!r}.")


def check_actor_greedy_weight(actor_greedy_weight: object) -> None:
    """
    Raise ``ValueError`` unless ``actor_greedy_weight`` is a finite number >= 0 (see :class:`ADC`).

    :param actor_greedy_weight: Weight of the actor's pull toward the best interval centre
    """
    if (
        isinstance(actor_greedy_weight, bool)
        or not isinstance(actor_greedy_weight, (int, float))
        or not 0 <= actor_greedy_weight < float("inf")
    ):
        raise ValueError(f"`actor_greedy_weight` must be a finite number >= 0, got {actor_greedy_weight!r}.")


def check_fast_update(fast_update: object) -> None:
    """
    Raise ``ValueError`` unless ``fast_update`` is a bool (see :class:`ADC`).

    :param fast_update: Whether ADC trains with its fast update path
    """
    if not isinstance(fast_update, bool):
        raise ValueError(f"`fast_update` must be true or false, got {fast_update!r}.")


class ADC(CheckedModelFiles, TD3WithCriticLearningRate):
    """
    Actor-Dueling-Critic (ADC).

    The Actor-Dueling-Critic Method for Reinforcement Learning (Wu et al., Sensors 2019): a deterministic
    policy-gradient actor trained against a *dueling* critic whose advantage stream has one output per
    uniform interval of the action range, ``Q = V + A(s, z_a) - mean_z A(s, z)`` (Eq. 13-14), with
    experience replay and soft target updates (Algorithm 1). Use
    :class:`~sb3_adc.common.noise.EpsilonGaussianNoise` as ``action_noise`` for the paper's exploration.

    That interval critic is ``policy_kwargs=dict(critic_design="paper")``. The default critic,
    ``critic_design="legendre"``, is not an interval critic in effect: its advantage is a polynomial in the
    action with state-dependent coefficients, ``A(s, a) = sum_k c_k(s) P_k(a)`` (the family of NAF and
    Q-functionals), and the interval baseline it subtracts, the mean of each Legendre term over the interval
    centres, is below 1.7e-4 for 100 intervals and 4.2e-3 for 20 (at the default degree 4). So ``n_intervals``
    barely matters for it: it shifts ``Q(s, .)`` by a constant in the action and leaves ``dQ/da``, which the
    actor follows, unchanged (see :mod:`sb3_adc.adc.designs`). It matters with ``target_greedy_mix``,
    ``actor_greedy_weight`` (they search the grid of interval centres, ``n_intervals`` points per action dimension,
    for the best action) and ``interval_exploration`` (it draws among those intervals).

    ADC is a special case of TD3, the way SB3's DDPG is, with a
    :class:`~sb3_adc.adc.policies.DuelingIntervalCritic` in place of the critic. Its defaults follow the
    paper, except the critic design: one critic, the actor updated at every gradient step, no target-policy
    smoothing, soft target updates, and a critic learning rate twice the actor's. The other defaults are SB3
    DDPG's, so ADC is a drop-in comparison against it.

    :param policy: The policy model to use (MlpPolicy, CnnPolicy, MultiInputPolicy, or an ``ADCPolicy``
        subclass)
    :param env: The environment to learn from (if registered in Gym, can be str); its action space must be
        a ``Box`` with finite bounds
    :param learning_rate: learning rate of the actor's Adam optimizer; it can be a function of the current
        progress remaining (from 1 to 0)
    :param critic_learning_rate: learning rate of the critic's optimizer (a float or a schedule);
        ``None`` (default) uses twice ``learning_rate`` at every point of training, as in the paper
    :param buffer_size: size of the replay buffer
    :param learning_starts: how many steps of the model to collect transitions for before learning starts
    :param batch_size: Minibatch size for each gradient update
    :param tau: the soft update coefficient ("Polyak update", between 0 and 1)
    :param gamma: the discount factor
    :param train_freq: Update the model every ``train_freq`` steps. Alternatively pass a tuple of frequency and
        unit like ``(5, "step")`` or ``(2, "episode")``.
    :param gradient_steps: How many gradient steps to do after each rollout (see ``train_freq``).
        Set to ``-1`` means to do as many gradient steps as steps done in the environment during the rollout.
    :param action_noise: the action noise type (None by default);
        :class:`~sb3_adc.common.noise.EpsilonGaussianNoise` gives the paper's epsilon-gated exploration
    :param replay_buffer_class: Replay buffer class to use (for instance ``HerReplayBuffer``).
        If ``None``, it will be automatically selected.
    :param replay_buffer_kwargs: Keyword arguments to pass to the replay buffer on creation.
    :param optimize_memory_usage: Enable a memory efficient variant of the replay buffer
        at a cost of more complexity.
    :param n_steps: When ``n_steps > 1``, uses n-step returns (with SB3's ``NStepReplayBuffer``) when updating
        the Q-value network.
    :param policy_delay: The actor and the target networks are updated once every ``policy_delay`` gradient
        steps (1 in the paper)
    :param target_policy_noise: Standard deviation of the target-policy smoothing noise (0, none, in the paper;
        use it with ``policy_kwargs=dict(n_critics=2)`` for a TD3-style variant)
    :param target_noise_clip: Limit for absolute value of target policy smoothing noise.
    :param target_greedy_mix: Not in the paper: the share ``m`` in ``[0, 1]`` of the greedy value in the TD target's
        next-state value (Eq. 11 read as "V is the greedy value"), ``(1 - m) Q'(s', mu'(s') [+ smoothing noise]) +
        m Q'(s', z*)`` with ``z* = argmax_z Q_1(s', z)`` over the grid of interval centres, chosen by the first
        *online* critic and valued by the *target* critics (double-Q style; with several critics, the minimum of
        the target critics at ``z*``). 0 (default): the paper's target. Needs a critic design in
        ``GREEDY_CRITIC_DESIGNS`` (``"legendre"``, the default)
    :param actor_greedy_weight: Not in the paper: the weight ``w >= 0`` of a greedy policy-improvement term added
        to the actor loss, ``w * mean_s 1[Q_1(s, z*) > Q_1(s, mu(s))] ||mu(s) - z*(s)||^2``: a pull toward the
        best interval centre, only on the states where it beats the actor's action, which can move the actor out
        of a local optimum of ``Q_1(s, .)`` that the gradient alone keeps it in. 0 (default): the paper's actor
        loss. Needs a critic design in ``GREEDY_CRITIC_DESIGNS``
    :param interval_exploration: Not in the paper: exploration from the advantages, the probability ``p`` in ``[0, 1]``
        that each action component, when collecting experience after ``learning_starts``, is drawn from
        ``softmax_z(A_1(s, z) / T)`` over its intervals (uniformly within the drawn one) instead of the actor plus
        ``action_noise`` (:mod:`sb3_adc.adc.exploration`). 0 (default): the paper's exploration. Needs a critic design
        in ``GREEDY_CRITIC_DESIGNS``
    :param interval_temperature: The temperature ``T > 0`` of that draw, in the units of the critic's Q-values
    :param fast_update: Not in the paper, and not a change to what is learned: ``True`` trains with the fast update
        path, which changes float rounding only (10 fresh seeds on the noisy Pendulum learn the same; opt-in, so
        that the committed results, made with the plain path, re-run digit for digit): fused Adam steps (unless
        ``optimizer_kwargs`` choose ``foreach`` or ``fused``), the twin critics of the default ``"legendre"`` design
        evaluated as one batched module (:mod:`sb3_adc.adc.stacked`), one Polyak update over all target parameters,
        and the losses kept as tensors and logged once per :meth:`train` call. ``False`` (default): the plain path,
        one critic after the other, per-parameter optimizer steps and Polyak updates (as SB3's TD3)
    :param stats_window_size: Window size for the rollout logging, specifying the number of episodes to average
        the reported success rate, mean episode length, and mean reward over
    :param tensorboard_log: the log location for tensorboard (if None, no logging)
    :param policy_kwargs: additional arguments to be passed to the policy on creation, among them
        ``critic_design``, ``n_intervals``, ``value_net_arch``, ``advantage_net_arch``, ``aggregation``,
        ``advantage_interpolation`` and ``n_critics`` (see :class:`~sb3_adc.adc.policies.ADCPolicy`)
    :param verbose: Verbosity level: 0 for no output, 1 for info messages (such as device or wrappers used),
        2 for debug messages
    :param seed: Seed for the pseudo random generators
    :param device: Device (cpu, cuda, ...) on which the code should be run.
        Setting it to auto, the code will be run on the GPU if possible.
    :param _init_setup_model: Whether or not to build the network at the creation of the instance
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": MlpPolicy,
        "CnnPolicy": CnnPolicy,
        "MultiInputPolicy": MultiInputPolicy,
    }
    policy: ADCPolicy
    critic: DuelingIntervalCritic  # type: ignore[assignment]
    critic_target: DuelingIntervalCritic  # type: ignore[assignment]

    def __init__(
        self,
        policy: str | type[ADCPolicy],
        env: GymEnv | str,
        learning_rate: float | Schedule = 1e-3,
        critic_learning_rate: float | Schedule | None = None,
        buffer_size: int = 1_000_000,
        learning_starts: int = 100,
        batch_size: int = 256,
        tau: float = 0.005,
        gamma: float = 0.99,
        train_freq: int | tuple[int, str] = 1,
        gradient_steps: int = 1,
        action_noise: ActionNoise | None = None,
        replay_buffer_class: type[ReplayBuffer] | None = None,
        replay_buffer_kwargs: dict[str, Any] | None = None,
        optimize_memory_usage: bool = False,
        n_steps: int = 1,
        policy_delay: int = 1,
        target_policy_noise: float = 0.0,
        target_noise_clip: float = 0.0,
        target_greedy_mix: float = 0.0,
        actor_greedy_weight: float = 0.0,
        interval_exploration: float = 0.0,
        interval_temperature: float = 1.0,
        fast_update: bool = False,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ):
        check_target_greedy_mix(target_greedy_mix)
        check_actor_greedy_weight(actor_greedy_weight)
        check_interval_exploration(interval_exploration)
        check_interval_temperature(interval_temperature)
        check_fast_update(fast_update)
        if env is not None:
            # Check the action space before SB3 does, for an error that says what ADC accepts.
            env = maybe_make_env(env, verbose)
            check_action_space(env.action_space)
            check_action_noise(action_noise, env.action_space)
        super().__init__(
            policy=policy,
            env=env,
            learning_rate=learning_rate,
            buffer_size=buffer_size,
            learning_starts=learning_starts,
            batch_size=batch_size,
            tau=tau,
            gamma=gamma,
            train_freq=train_freq,
            gradient_steps=gradient_steps,
            action_noise=action_noise,
            replay_buffer_class=replay_buffer_class,
            replay_buffer_kwargs=replay_buffer_kwargs,
            optimize_memory_usage=optimize_memory_usage,
            n_steps=n_steps,
            policy_delay=policy_delay,
            target_policy_noise=target_policy_noise,
            target_noise_clip=target_noise_clip,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=False,
        )
        self.critic_learning_rate = critic_learning_rate
        self.target_greedy_mix = float(target_greedy_mix)
        self.actor_greedy_weight = float(actor_greedy_weight)
        self.interval_exploration = float(interval_exploration)
        self.interval_temperature = float(interval_temperature)
        self.fast_update = fast_update
        self._last_batch: tuple[PyTorchObs, th.Tensor] | None = None
        if _init_setup_model:
            self._setup_model()

    def _setup_model(self) -> None:
        if not (isinstance(self.policy_class, type) and issubclass(self.policy_class, ADCPolicy)):
            raise TypeError(
                f"`policy` must be one of {sorted(self.policy_aliases)} or a subclass of ADCPolicy, got "
                f"{self.policy_class!r}. (Loading a model file saved by another algorithm? Load it with that "
                "algorithm's class.)"
            )
        # Record the critic design in the saved policy_kwargs, so that a file keeps its design if the default changes.
        self.policy_kwargs = {"critic_design": DEFAULT_CRITIC_DESIGN, **self.policy_kwargs}
        super()._setup_model()
        if self.critic.critic_design not in GREEDY_CRITIC_DESIGNS:
            for name in ("target_greedy_mix", "actor_greedy_weight", "interval_exploration"):
                if getattr(self, name) > 0:
                    raise ValueError(
                        f"`{name}` needs the Q-value of every interval centre, which critic_design="
                        f"{self.critic.critic_design!r} does not give in one pass: use a critic_design in "
                        f"{GREEDY_CRITIC_DESIGNS} or {name}=0."
                    )
        # Parameter lists of the per-step updates, gathered once rather than at every gradient step.
        self._actor_parameters = list(self.actor.parameters())
        self._target_updates = [
            (list(self.critic.parameters()), list(self.critic_target.parameters())),
            (self._actor_parameters, list(self.actor_target.parameters())),
        ]
        # The fast path's batched twin critics, online and target (see `_link_stacked_critics`).
        self._stacked_critics: tuple[StackedCritics, StackedCritics] | None = None
        # The fast path's optimizer steps, actor's and critic's (see `_fast_steps`).
        self._fused_steps: tuple[FusedAdamStep, FusedAdamStep] | None = None

    def _default_critic_lr_schedule(self) -> Schedule:
        """The paper's critic rate, twice the actor's at every point of training (``critic_learning_rate=None``)."""
        return ScaledSchedule(self.lr_schedule, PAPER_CRITIC_LR_FACTOR)

    def _link_stacked_critics(self) -> tuple[StackedCritics, StackedCritics] | None:
        """
        The fast path's batched online and target critics, for a critic design that allows them (:func:`stackable`),
        built or re-linked to the critics' parameters when needed (a loaded or moved policy); ``None`` otherwise.
        """
        if not stackable(self.critic):
            self._stacked_critics = None
        elif self._stacked_critics is None or self._stacked_critics[0].critic is not self.critic:
            self._stacked_critics = (StackedCritics(self.critic, True), StackedCritics(self.critic_target, False))
        else:
            for stacked in self._stacked_critics:
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

    def _sample_action(
        self, learning_starts: int, action_noise: ActionNoise | None = None, n_envs: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """SB3's exploration (uniform warm-up, then the actor plus ``action_noise``), then ``interval_exploration``'s
        draws (:func:`~sb3_adc.adc.exploration.explore_from_advantages`). Parameters and return as SB3's."""
        action, buffer_action = super()._sample_action(learning_starts, action_noise, n_envs)
        if self.interval_exploration == 0 or self.num_timesteps < learning_starts or self._last_obs is None:
            return action, buffer_action
        actions = th.as_tensor(buffer_action, device=self.device)
        # The critic's pass, only if a component is drawn.
        advantages = partial(self.critic.interval_advantages, self.policy.obs_to_tensor(self._last_obs)[0])
        p, temperature = self.interval_exploration, self.interval_temperature
        buffer_action = explore_from_advantages(actions, advantages, self.critic.partition.edges, p, temperature).cpu().numpy()
        return self.policy.unscale_action(buffer_action), buffer_action

    def dump_logs(self) -> None:
        """Write log data, with the critic's diagnostics on the last training batch: ``train/value_mean`` (mean of
        the first critic's value stream) and ``train/advantage_std`` (spread of its advantage stream over the
        intervals, averaged over the batch and the action dimensions)."""
        if self._last_batch is not None:
            with th.no_grad():
                value, advantages, _ = self.critic.decompose(*self._last_batch)
            self.logger.record("train/value_mean", value.mean().item())
            self.logger.record("train/advantage_std", advantages.std(dim=-1).mean().item())
        super().dump_logs()

    def learn(
        self: SelfADC,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 4,
        tb_log_name: str = "ADC",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfADC:
        return super().learn(
            total_timesteps=total_timesteps,
            callback=callback,
            log_interval=log_interval,
            tb_log_name=tb_log_name,
            reset_num_timesteps=reset_num_timesteps,
            progress_bar=progress_bar,
        )

    def _excluded_save_params(self) -> list[str]:
        # The last training batch is kept for the logged diagnostics only; the parameter lists are the policy's.
        return [
            *super()._excluded_save_params(),
            "_last_batch",
            "_actor_parameters",
            "_target_updates",
            "_stacked_critics",
            "_fused_steps",
        ]

    def _check_saved_parameters(self, params: dict[str, Any]) -> None:
        """
        Check that the parameters were made by an ADC model with this model's ``n_intervals`` (their tensor
        shapes are checked next, by :meth:`~sb3_adc.common.model_files.CheckedModelFiles.set_parameters`).

        :param params: Module name to state dict
        :raises ModelFileError: for a critic of another algorithm or another ``n_intervals``
        """
        policy_state = params.get("policy")
        if not isinstance(policy_state, dict):
            return
        edges = policy_state.get("critic.partition.edges")
        if edges is None:
            if any(key.startswith("critic.") for key in policy_state):
                raise model_file_error(
                    "The parameters were not saved by an ADC model (no dueling interval critic found); "
                    "load them with the class of the algorithm that saved them."
                )
            return
        saved = int(edges.shape[0]) - 1
        if saved != self.policy.n_intervals:
            raise model_file_error(
                f"`n_intervals` mismatch: the saved critic has n_intervals={saved}, this model has "
                f"n_intervals={self.policy.n_intervals}. Build the model with policy_kwargs=dict(n_intervals={saved})."
            )

    @classmethod
    def _load_arguments(
        cls,
        path: str | pathlib.Path | io.BufferedIOBase,
        env: GymEnv | None,
        custom_objects: dict[str, Any] | None,
        kwargs: dict[str, Any],
    ) -> tuple[dict[str, Any] | None, dict[str, Any]]:
        """
        What :meth:`load` (:meth:`~sb3_adc.common.model_files.CheckedModelFiles.load`, whose errors name the file)
        passes to SB3's: an ``env`` whose action space ADC cannot act in raises a ``ModelFileError`` that is also an
        :class:`~sb3_adc.common.spaces.ActionSpaceError`; a file saved before ``critic_design`` existed loads with
        the paper's critic; given ``policy_kwargs`` without a critic design mean the file's.

        :param path: The file given to :meth:`load`
        :param env: The environment given to :meth:`load`; its spaces must match the saved ones
        :param custom_objects: The caller's ``custom_objects``
        :param kwargs: The caller's extra keyword arguments
        """
        if env is not None:
            try:
                check_action_space(env.action_space)
            except ActionSpaceError as error:
                # SB3's load reports the env's mismatched space as a ValueError: be one too, and name the file.
                raise model_file_error(f"Cannot load the ADC model {path!s} for this env: {error}", type(error)) from error
        custom_objects = _design_of_files_without_one(path, custom_objects)
        given = kwargs.get("policy_kwargs")
        if isinstance(given, dict) and "critic_design" not in given:
            # SB3 refuses policy_kwargs that differ from the saved ones, which record the critic design (see
            # `_setup_model`): the given ones mean the design they meant at construction, the file's.
            saved = (custom_objects or {}).get("policy_kwargs") or {}
            kwargs = {**kwargs, "policy_kwargs": {"critic_design": saved.get("critic_design", DEFAULT_CRITIC_DESIGN), **given}}
        return custom_objects, kwargs


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


def _design_of_files_without_one(
    path: str | pathlib.Path | io.BufferedIOBase, custom_objects: dict[str, Any] | None
) -> dict[str, Any] | None:
    """
    ``custom_objects`` that load a file saved before ``critic_design`` existed with the critic it holds, the paper's
    (``critic_design="paper"``), rather than with today's default.

    :param path: The model file, or a file-like (read, then rewound)
    :param custom_objects: The caller's ``custom_objects``; returned unchanged when they set ``policy_kwargs``
    """
    if custom_objects is not None and "policy_kwargs" in custom_objects:
        return custom_objects
    position = path.tell() if isinstance(path, io.BufferedIOBase) else None
    data, _, _ = load_from_zip_file(path, custom_objects=custom_objects, device="cpu", print_system_info=False)
    if position is not None:
        assert isinstance(path, io.BufferedIOBase)
        path.seek(position)
    policy_kwargs = (data or {}).get("policy_kwargs")
    if not isinstance(policy_kwargs, dict) or "critic_design" in policy_kwargs:
        return custom_objects
    return {**(custom_objects or {}), "policy_kwargs": {**policy_kwargs, "critic_design": "paper"}}
