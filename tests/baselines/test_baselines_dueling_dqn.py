"""The dueling Q-network policy for SB3's DQN, over discretised Pendulum actions."""

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import DQN

from sb3_adc.baselines import DuelingDQNPolicy, DuelingQNetwork
from sb3_adc_envs.wrappers import DiscretizedActions

TINY = {"net_arch": [8], "value_net_arch": [4], "advantage_net_arch": [6]}


def make_model(**kwargs):
    env = DiscretizedActions(gym.make("Pendulum-v1"), 25)
    return DQN(DuelingDQNPolicy, env, learning_starts=50, buffer_size=500, batch_size=16, policy_kwargs=TINY, seed=0, **kwargs)


def test_dueling_identity():
    model = make_model()
    q_net = model.q_net
    assert isinstance(q_net, DuelingQNetwork)
    assert isinstance(model.q_net_target, DuelingQNetwork)
    obs = th.randn(7, 3)
    with th.no_grad():
        q_values = q_net(obs)
        value, advantages = q_net.value_and_advantages(obs)
    assert q_values.shape == (7, 25)
    assert value.shape == (7, 1)
    assert advantages.shape == (7, 25)
    # Q = V + A - mean(A): the mean of Q over actions is V, and Q and A differ by a per-state constant.
    th.testing.assert_close(q_values.mean(dim=1, keepdim=True), value)
    th.testing.assert_close(q_values - q_values.mean(dim=1, keepdim=True), advantages - advantages.mean(dim=1, keepdim=True))
    # The streams really are separate networks with the requested sizes.
    assert [m.out_features for m in q_net.trunk if isinstance(m, th.nn.Linear)] == [8]
    assert [m.out_features for m in q_net.value_stream if isinstance(m, th.nn.Linear)] == [4, 1]
    assert [m.out_features for m in q_net.advantage_stream if isinstance(m, th.nn.Linear)] == [6, 25]
    # Greedy actions are the argmax of the advantages.
    np.testing.assert_array_equal(q_net._predict(obs).numpy(), advantages.argmax(dim=1).numpy())


def test_learns_saves_and_loads(tmp_path):
    model = make_model(target_update_interval=50)
    model.learn(200)
    obs = th.randn(5, 3)
    with th.no_grad():
        expected = model.q_net(obs)
    model.save(tmp_path / "dueling")
    loaded = DQN.load(tmp_path / "dueling")
    assert isinstance(loaded.policy, DuelingDQNPolicy)
    assert loaded.policy.dueling_kwargs == {"value_net_arch": [4], "advantage_net_arch": [6]}
    with th.no_grad():
        th.testing.assert_close(loaded.q_net(obs), expected)
    action, _ = loaded.predict(np.zeros(3, dtype=np.float32), deterministic=True)
    assert 0 <= int(action) < 25


def test_needs_a_discrete_action_space():
    with pytest.raises(TypeError, match=r"DuelingDQNPolicy needs a Discrete action space.*DiscretizedActions"):
        DuelingDQNPolicy(gym.make("Pendulum-v1").observation_space, gym.make("Pendulum-v1").action_space, lambda _: 1e-3)
