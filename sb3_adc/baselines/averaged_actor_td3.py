"""SB3's TD3 with the averaged actor ADC can deploy, so that a comparison can give both algorithms the same option."""

from __future__ import annotations

from sb3_adc.adc.policies import refuse_adc_policy
from sb3_adc.common.actor_average import TD3WithActorAverage
from sb3_adc.common.model_files import CheckedModelFiles


class AveragedActorTD3(CheckedModelFiles, TD3WithActorAverage):
    """
    Twin Delayed DDPG (SB3's :class:`~stable_baselines3.TD3`, update for update) whose ``MlpPolicy`` takes
    ``actor_average_tau``: the deployed policy is then a Polyak average of the actor's iterates, as
    :class:`~sb3_adc.ADC` can deploy (:mod:`sb3_adc.common.actor_average`). Without it (the default) the model is
    SB3's TD3.

    Unlike SB3's TD3 it refuses an :class:`~sb3_adc.adc.policies.ADCPolicy` (SB3's ``TD3.load`` of an ADC model file
    silently trains the ADC policy with TD3's update), and its ``load`` and ``set_parameters`` errors name the file
    (see :meth:`sb3_adc.ADC.load`). The constructor's parameters are SB3's TD3's.
    """

    def _setup_model(self) -> None:
        refuse_adc_policy(self.policy_class, "TD3")
        super()._setup_model()
