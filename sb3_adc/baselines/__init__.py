"""
The baselines of the ADC paper, as SB3 algorithms and policies.

- :class:`SplitRateDDPG`: SB3's DDPG with a separate critic learning rate (the paper's DDPG) and the averaged actor;
- :class:`AveragedActorTD3`: SB3's TD3 with the averaged actor ADC can deploy (``actor_average_tau``);
- :class:`VanillaActorCritic`: online deterministic actor-critic, no replay, no target networks;
- :class:`DuelingDQNPolicy`: a dueling Q-network policy for SB3's DQN, used with
  :class:`~sb3_adc_envs.wrappers.DiscretizedActions` for the paper's dueling network over 25 actions.
"""

from sb3_adc.baselines.averaged_actor_td3 import AveragedActorTD3
from sb3_adc.baselines.dueling_dqn import DuelingDQNPolicy, DuelingQNetwork
from sb3_adc.baselines.split_rate_ddpg import SplitRateDDPG
from sb3_adc.baselines.vanilla_actor_critic import VANILLA_SETTINGS, VanillaActorCritic

__all__ = [
    "VANILLA_SETTINGS",
    "AveragedActorTD3",
    "DuelingDQNPolicy",
    "DuelingQNetwork",
    "SplitRateDDPG",
    "VanillaActorCritic",
]
