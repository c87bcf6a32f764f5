"""DuelingIntervalCritic honours SB3's ContinuousCritic contract and computes Eq. 13-14."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3.common.utils import ConstantSchedule

from sb3_adc.adc.policies import ADCPolicy, DuelingIntervalCritic


def make_policy(action_dim=1, **kwargs):
    observation_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
    action_space = spaces.Box(-2.0, 2.0, (action_dim,), np.float32)
    kwargs.setdefault("net_arch", [16])
    kwargs.setdefault("n_intervals", 10)
    # This module tests the paper's form of the critic; tests/adc/test_critic_designs.py covers the others.
    kwargs.setdefault("critic_design", "paper")
    return ADCPolicy(observation_space, action_space, ConstantSchedule(1e-3), **kwargs)


def batch(action_dim=1, size=8, seed=0):
    generator = th.Generator().manual_seed(seed)
    obs = th.rand(size, 3, generator=generator) * 2 - 1
    actions = th.rand(size, action_dim, generator=generator) * 2 - 1
    return obs, actions


@pytest.mark.parametrize("n_critics", [1, 2, 3])
def test_forward_returns_one_q_column_per_critic(n_critics):
    critic = make_policy(n_critics=n_critics).critic
    obs, actions = batch()
    q_values = critic(obs, actions)
    assert isinstance(q_values, tuple)
    assert len(q_values) == n_critics
    assert all(q.shape == (8, 1) for q in q_values)
    th.testing.assert_close(critic.q1_forward(obs, actions), q_values[0])


@pytest.mark.parametrize("action_dim", [1, 3])
def test_decompose_shapes_and_interval_index(action_dim):
    critic = make_policy(action_dim=action_dim, n_intervals=6).critic
    obs, actions = batch(action_dim)
    value, advantages, interval_index = critic.decompose(obs, actions)
    assert value.shape == (8, 1)
    assert advantages.shape == (8, action_dim, 6)
    assert interval_index.shape == (8, action_dim)
    expected_index = th.clamp(((actions + 1) / 2 * 6).floor().long(), 0, 5)
    assert th.equal(interval_index, expected_index)


def reference_q(value, advantages, actions, aggregation, interpolation):
    """Eq. 11 / 13-14 written out with explicit lookups, one branch per action dimension."""
    n = advantages.shape[-1]
    if interpolation == "none":
        index = th.clamp(((actions + 1) / 2 * n).floor().long(), 0, n - 1)
        selected = advantages.gather(-1, index.unsqueeze(-1)).squeeze(-1)
    else:
        position = ((actions + 1) * n / 2 - 0.5).clamp(0, n - 1)
        lower = position.floor().clamp(max=n - 2).long()
        share = position - lower
        below = advantages.gather(-1, lower.unsqueeze(-1)).squeeze(-1)
        above = advantages.gather(-1, (lower + 1).unsqueeze(-1)).squeeze(-1)
        selected = (1 - share) * below + share * above
    baseline = advantages.mean(-1) if aggregation == "mean" else advantages.max(-1).values
    return value + (selected - baseline).sum(-1, keepdim=True)


@pytest.mark.parametrize("interpolation", ["none", "linear"])
@pytest.mark.parametrize("aggregation", ["mean", "max"])
@pytest.mark.parametrize(("value_net_arch", "advantage_net_arch"), [([], []), ([8], []), ([], [8]), ([8], [8])])
@pytest.mark.parametrize("action_dim", [1, 2])
def test_q_equals_value_plus_centred_advantage_of_the_action_interval(
    action_dim, value_net_arch, advantage_net_arch, aggregation, interpolation
):
    critic = make_policy(
        action_dim=action_dim,
        value_net_arch=value_net_arch,
        advantage_net_arch=advantage_net_arch,
        aggregation=aggregation,
        advantage_interpolation=interpolation,
    ).critic
    obs, actions = batch(action_dim)
    value, advantages, _ = critic.decompose(obs, actions)
    expected = reference_q(value, advantages, actions, aggregation, interpolation)
    th.testing.assert_close(critic(obs, actions)[0], expected)


@pytest.mark.parametrize("value_net_arch", [[], [8]])
def test_max_aggregation_gives_q_at_most_value(value_net_arch):
    critic = make_policy(aggregation="max", value_net_arch=value_net_arch).critic
    obs, actions = batch(size=64)
    value, _, _ = critic.decompose(obs, actions)
    assert th.all(critic(obs, actions)[0] <= value + 1e-6)


@pytest.mark.parametrize("interpolation", ["none", "linear"])
def test_q_has_a_gradient_with_respect_to_the_action(interpolation):
    critic = make_policy(advantage_interpolation=interpolation).critic
    obs, actions = batch()
    actions.requires_grad_(True)
    critic.q1_forward(obs, actions).sum().backward()
    assert actions.grad is not None
    assert th.all(actions.grad.abs() > 0)


def test_linear_interpolation_adds_the_advantage_slope_to_the_action_gradient():
    policy = make_policy(advantage_interpolation="linear", n_intervals=4)
    critic = policy.critic
    obs, actions = batch(size=1)
    actions = actions.requires_grad_(True)
    q = critic.q1_forward(obs, actions)
    (grad_linear,) = th.autograd.grad(q.sum(), actions)
    critic.advantage_interpolation = "none"
    q_none = critic.q1_forward(obs, actions)
    (grad_none,) = th.autograd.grad(q_none.sum(), actions)
    assert not th.allclose(grad_linear, grad_none)


def test_paper_pendulum_network_is_expressible():
    policy = make_policy(net_arch=dict(pi=[30], qf=[30]), n_intervals=100, value_net_arch=[20])
    sizes = policy.critic.q_networks[0].stream_layer_sizes()
    assert sizes == {"trunk": [(3 + 1, 30)], "value": [(30, 20), (20, 1)], "advantage": [(30, 100)]}
    actor_linear = [m for m in policy.actor.mu if isinstance(m, th.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in actor_linear] == [(3, 30), (30, 1)]


def test_stream_layers_follow_their_net_arch():
    policy = make_policy(action_dim=2, net_arch=[16, 12], n_intervals=5, value_net_arch=[6, 4], advantage_net_arch=[9])
    sizes = policy.critic.q_networks[0].stream_layer_sizes()
    assert sizes == {
        "trunk": [(3 + 2, 16), (16, 12)],
        "value": [(12, 6), (6, 4), (4, 1)],
        "advantage": [(12, 9), (9, 2 * 5)],
    }


def test_fused_first_stream_layer_equals_two_separate_layers():
    q_net = make_policy(value_net_arch=[4]).critic.q_networks[0]
    hidden = th.randn(5, 16)
    weight, bias = q_net.stream_inputs.weight, q_net.stream_inputs.bias
    value_part = th.nn.functional.linear(hidden, weight[:4], bias[:4])
    advantage_part = th.nn.functional.linear(hidden, weight[4:], bias[4:])
    value_input, advantage_input = q_net.stream_inputs(hidden).split(q_net.split_sizes, dim=1)
    th.testing.assert_close(value_input, value_part)
    th.testing.assert_close(advantage_input, advantage_part)


def test_empty_trunk_feeds_features_and_action_to_both_streams():
    critic = make_policy(net_arch=[], value_net_arch=[4]).critic
    q_net = critic.q_networks[0]
    assert len(q_net.trunk) == 0
    assert q_net.stream_layer_sizes()["value"][0] == (3 + 1, 4)
    obs, actions = batch()
    assert critic(obs, actions)[0].shape == (8, 1)


def test_shared_features_extractor_is_not_trained_by_the_critic_loss():
    policy = make_policy(share_features_extractor=True, features_extractor_class=_LinearExtractor)
    critic = policy.critic
    assert critic.features_extractor is policy.actor.features_extractor
    obs, actions = batch()
    critic(obs, actions)[0].sum().backward()
    assert critic.features_extractor.linear.weight.grad is None
    policy_separate = make_policy(share_features_extractor=False, features_extractor_class=_LinearExtractor)
    policy_separate.critic(obs, actions)[0].sum().backward()
    assert policy_separate.critic.features_extractor.linear.weight.grad is not None


def test_interval_edges_travel_with_the_state_dict():
    policy = make_policy(n_intervals=12)
    state = policy.state_dict()
    assert state["critic.partition.edges"].shape == (13,)
    assert state["critic_target.partition.edges"].shape == (13,)


def test_critic_direct_construction_validates_options():
    policy = make_policy()
    kwargs = dict(policy.critic_kwargs, features_extractor=policy.make_features_extractor(), features_dim=3)
    with pytest.raises(ValueError, match="n_critics"):
        DuelingIntervalCritic(**{**kwargs, "n_critics": 0})
    with pytest.raises(ValueError, match="aggregation"):
        DuelingIntervalCritic(**kwargs, aggregation="sum")


class _LinearExtractor(th.nn.Module):
    """A features extractor with a trainable layer, to observe where its gradients come from."""

    def __init__(self, observation_space, features_dim=4):
        super().__init__()
        self.features_dim = features_dim
        self.linear = th.nn.Linear(int(np.prod(observation_space.shape)), features_dim)

    def forward(self, observations):
        return self.linear(observations)
