from __future__ import annotations

import io
from functools import partial
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from stable_baselines3.common.base_class import maybe_make_env
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule

from sb3_adc.adc.exploration import explore_from_advantages
from sb3_adc.adc.options import (
    check_actor_greedy_weight,
    check_fast_update,
    check_interval_exploration,
    check_interval_temperature,
    check_target_greedy_mix,
)
from sb3_adc.adc.policies import (
    DEFAULT_CRITIC_DESIGN,
    GREEDY_CRITIC_DESIGNS,
    ADCPolicy,
    CnnPolicy,
    MlpPolicy,
    MultiInputPolicy,
)
from sb3_adc.adc.update import ADCUpdate
from sb3_adc.common.critic_learning_rate import TD3WithCriticLearningRate
from sb3_adc.common.model_files import CheckedModelFiles, LoadArguments, ModelPath, model_file_error
from sb3_adc.common.noise import check_action_noise
from sb3_adc.common.schedules import ScaledSchedule
from sb3_adc.common.spaces import ActionSpaceError, check_action_space

SelfADC = TypeVar("SelfADC", bound="ADC")

#: Ratio of the critic's to the actor's learning rate in the ADC paper (Tables 1-3).
PAPER_CRITIC_LR_FACTOR = 2.0


class ADC(CheckedModelFiles, TD3WithCriticLearningRate, ADCUpdate):
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
    :param action_noise: the action noise type (None by default, as SB3's: at the defaults the paper's noise was
        level with none on Pendulum-v1, see the ADC page's "Default exploration");
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

    def _default_critic_lr_schedule(self) -> Schedule:
        """The paper's critic rate, twice the actor's at every point of training (``critic_learning_rate=None``)."""
        return ScaledSchedule(self.lr_schedule, PAPER_CRITIC_LR_FACTOR)

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
        cls, path: ModelPath, env: GymEnv | None, custom_objects: dict[str, Any] | None, kwargs: dict[str, Any]
    ) -> LoadArguments:
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


def _design_of_files_without_one(path: ModelPath, custom_objects: dict[str, Any] | None) -> dict[str, Any] | None:
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
