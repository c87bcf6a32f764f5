"""A learning rate of its own for the critic of SB3's TD3 family (TD3, DDPG, ADC)."""

from __future__ import annotations

import torch as th
from stable_baselines3.common.type_aliases import Schedule
from stable_baselines3.common.utils import FloatSchedule, update_learning_rate
from stable_baselines3.td3.td3 import TD3


class TD3WithCriticLearningRate(TD3):
    """
    TD3 (or a subclass such as DDPG) whose critic has its own learning rate.

    SB3's TD3 and DDPG update the actor's and the critic's optimizers with one ``learning_rate``; the ADC
    paper trains the critic at twice the actor's rate (Tables 1-3). Subclasses set ``critic_learning_rate``
    (a float, a schedule of the progress remaining, or ``None``) before ``_setup_model`` runs; ``None`` means
    :meth:`_default_critic_lr_schedule`, which is derived from ``lr_schedule`` whenever it is read, so that
    replacing ``model.lr_schedule`` on a live model (as SB3's own tests and users fine-tuning a model do) moves
    the critic's rate with the actor's. Both schedules are followed through training, logged
    (``train/learning_rate`` and ``train/critic_learning_rate``), and rebuilt on load.
    """

    critic_learning_rate: float | Schedule | None
    _critic_lr_schedule: Schedule | None = None

    def _default_critic_lr_schedule(self) -> Schedule:
        """The critic's schedule when ``critic_learning_rate`` is ``None``: the actor's."""
        return self.lr_schedule

    @property
    def critic_lr_schedule(self) -> Schedule:
        """
        The critic's learning-rate schedule: ``critic_learning_rate`` as a schedule, or, when it is ``None``,
        :meth:`_default_critic_lr_schedule` of the current ``lr_schedule``. Assigning a float or a schedule
        sets ``critic_learning_rate`` to it (and so is saved with the model).
        """
        if self.critic_learning_rate is None or self._critic_lr_schedule is None:
            return self._default_critic_lr_schedule()
        return self._critic_lr_schedule

    @critic_lr_schedule.setter
    def critic_lr_schedule(self, value: float | Schedule) -> None:
        self.critic_learning_rate = value
        self._critic_lr_schedule = FloatSchedule(value)

    def _setup_lr_schedule(self) -> None:
        super()._setup_lr_schedule()
        if self.critic_learning_rate is None:
            self._critic_lr_schedule = None
        else:
            self._critic_lr_schedule = FloatSchedule(self.critic_learning_rate)

    def _setup_model(self) -> None:
        super()._setup_model()
        update_learning_rate(self.critic.optimizer, self.critic_lr_schedule(1.0))

    def _update_learning_rate(self, optimizers: list[th.optim.Optimizer] | th.optim.Optimizer) -> None:
        """
        Set the learning rates for the current progress: the critic's optimizer follows
        ``critic_learning_rate``, every other optimizer ``learning_rate``.

        :param optimizers: An optimizer or a list of optimizers.
        """
        actor_lr = self.lr_schedule(self._current_progress_remaining)
        critic_lr = self.critic_lr_schedule(self._current_progress_remaining)
        self.logger.record("train/learning_rate", actor_lr)
        self.logger.record("train/critic_learning_rate", critic_lr)
        for optimizer in optimizers if isinstance(optimizers, list) else [optimizers]:
            update_learning_rate(optimizer, critic_lr if optimizer is self.critic.optimizer else actor_lr)

    def _excluded_save_params(self) -> list[str]:
        # Rebuilt from `critic_learning_rate` and `learning_rate` on load.
        return [*super()._excluded_save_params(), "_critic_lr_schedule"]
