"""SplitRateDDPG (DDPG with a critic learning rate; its averaged actor is tested with TD3's in
tests/baselines/test_averaged_actor_td3.py) and VanillaActorCritic (no replay, no target networks)."""

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import DDPG
from stable_baselines3.common.logger import configure

from sb3_adc.baselines import SplitRateDDPG, VanillaActorCritic

TINY = {"net_arch": [8]}


def learning_rates(model):
    return model.actor.optimizer.param_groups[0]["lr"], model.critic.optimizer.param_groups[0]["lr"]


def test_split_rate_ddpg_without_critic_rate_is_sb3_ddpg_update_for_update():
    kwargs = {"learning_starts": 50, "batch_size": 16, "buffer_size": 1000, "policy_kwargs": TINY, "seed": 3}
    ours = SplitRateDDPG("MlpPolicy", "Pendulum-v1", **kwargs).learn(150)
    theirs = DDPG("MlpPolicy", "Pendulum-v1", **kwargs).learn(150)
    for mine, reference in zip(ours.policy.parameters(), theirs.policy.parameters(), strict=True):
        th.testing.assert_close(mine, reference, rtol=0, atol=0)


def test_split_rate_ddpg_uses_both_rates_and_keeps_them_on_load(tmp_path):
    model = SplitRateDDPG("MlpPolicy", "Pendulum-v1", learning_rate=1e-3, critic_learning_rate=2e-3, policy_kwargs=TINY)
    assert learning_rates(model) == (1e-3, 2e-3)
    model.learning_starts = 10
    model.learn(30)
    assert learning_rates(model) == (1e-3, 2e-3)
    model.save(tmp_path / "ddpg")
    loaded = SplitRateDDPG.load(tmp_path / "ddpg")
    assert loaded.critic_learning_rate == 2e-3
    assert learning_rates(loaded) == (1e-3, 2e-3)


def test_split_rate_ddpg_critic_schedule():
    model = SplitRateDDPG(
        "MlpPolicy", "Pendulum-v1", critic_learning_rate=lambda progress: 4e-3 * progress, policy_kwargs=TINY
    )
    model.set_logger(configure(None, [""]))
    model._current_progress_remaining = 0.5
    model._update_learning_rate([model.actor.optimizer, model.critic.optimizer])
    assert learning_rates(model) == pytest.approx((1e-3, 2e-3))


def test_vanilla_actor_critic_learns_from_the_last_transition_only():
    env = gym.make("Pendulum-v1")
    model = VanillaActorCritic("MlpPolicy", env, learning_rate=1e-3, critic_learning_rate=2e-3, policy_kwargs=TINY, seed=0)
    assert (model.buffer_size, model.batch_size, model.tau) == (1, 1, 1.0)
    assert (model.train_freq.frequency, model.gradient_steps) == (1, 1)
    model.learn(40)
    buffer = model.replay_buffer
    assert buffer.buffer_size == 1
    # Every sample is the transition just stored: the observation the model is now acting from.
    samples = buffer.sample(8)
    np.testing.assert_allclose(samples.next_observations.numpy(), np.repeat(model._last_obs, 8, axis=0), rtol=1e-6)
    # One update per step, the first one after the first step.
    assert model._n_updates == 40
    assert learning_rates(model) == (1e-3, 2e-3)


def test_vanilla_actor_critic_has_no_lagging_target_networks():
    model = VanillaActorCritic("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, seed=1)
    model.learn(25)
    for online, target in ((model.critic, model.critic_target), (model.actor, model.actor_target)):
        for parameter, target_parameter in zip(online.parameters(), target.parameters(), strict=True):
            th.testing.assert_close(parameter, target_parameter, rtol=0, atol=0)


def test_vanilla_actor_critic_fixed_settings_are_not_parameters():
    with pytest.raises(TypeError, match="buffer_size"):
        VanillaActorCritic("MlpPolicy", "Pendulum-v1", buffer_size=5000)
