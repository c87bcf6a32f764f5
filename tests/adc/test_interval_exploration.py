"""Exploration from the advantages: a Boltzmann draw over the interval centres (``interval_exploration``)."""

import math

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3 import TD3
from stable_baselines3.common.env_util import make_vec_env

from sb3_adc import ADC
from sb3_adc.adc.exploration import boltzmann_interval_draw, explore_from_advantages
from sb3_adc.adc.intervals import UniformIntervalPartition
from sb3_adc.adc.policies import CRITIC_DESIGNS, GREEDY_CRITIC_DESIGNS
from sb3_adc.common.noise import EpsilonGaussianNoise

N_INTERVALS = 5
EDGES = UniformIntervalPartition(N_INTERVALS).edges  # -1, -0.6, -0.2, 0.2, 0.6, 1
NON_GREEDY_DESIGNS = [design for design in CRITIC_DESIGNS if design not in GREEDY_CRITIC_DESIGNS]
# Advantages of the five intervals in two action dimensions, with distinct, well-spread probabilities.
ADVANTAGES = th.tensor([[0.0, 1.0, -0.5, 2.0, 0.5], [-1.0, 0.0, 0.0, 1.5, -3.0]])
N_DRAWS = 20_000


def generator(seed=0):
    return th.Generator().manual_seed(seed)


def repeated(advantages, n=N_DRAWS):
    """The same state's advantages ``(action_dim, n_intervals)`` for ``n`` samples, ``(n, action_dim, n_intervals)``."""
    return advantages.expand(n, *advantages.shape)


@pytest.mark.parametrize("temperature", [0.5, 1.0, 3.0])
def test_drawn_intervals_follow_the_boltzmann_distribution_of_the_advantages(temperature):
    _, index = boltzmann_interval_draw(repeated(ADVANTAGES), EDGES, temperature, generator())
    expected = th.softmax(ADVANTAGES / temperature, dim=-1)
    for dim in range(ADVANTAGES.shape[0]):
        frequencies = th.bincount(index[:, dim], minlength=N_INTERVALS) / N_DRAWS
        binomial_std = (expected[dim] * (1 - expected[dim]) / N_DRAWS).sqrt()
        assert ((frequencies - expected[dim]).abs() <= 4 * binomial_std + 1e-6).all(), (dim, frequencies, expected[dim])


def test_draws_are_independent_across_action_dimensions():
    _, index = boltzmann_interval_draw(repeated(ADVANTAGES), EDGES, 1.0, generator())
    expected = th.softmax(ADVANTAGES, dim=-1)
    # The joint frequency of a pair of intervals is the product of the marginal probabilities.
    joint = ((index[:, 0] == 3) & (index[:, 1] == 3)).float().mean()
    product = expected[0, 3] * expected[1, 3]
    assert abs(joint - product) <= 4 * math.sqrt(product * (1 - product) / N_DRAWS)


@pytest.mark.parametrize("temperature", [1e-3, 1e-30])
def test_a_small_temperature_picks_the_best_interval(temperature):
    actions, index = boltzmann_interval_draw(repeated(ADVANTAGES, 2000), EDGES, temperature, generator())
    assert (index == ADVANTAGES.argmax(dim=-1)).all()
    assert th.isfinite(actions).all()


@pytest.mark.parametrize("n_intervals", [2, 5, 100])
def test_draws_stay_within_the_action_range_and_the_drawn_interval(n_intervals):
    partition = UniformIntervalPartition(n_intervals)
    advantages = th.randn(N_DRAWS, 3, n_intervals, generator=generator(1))
    actions, index = boltzmann_interval_draw(advantages, partition.edges, 0.7, generator())
    assert ((actions >= -1) & (actions <= 1)).all()
    assert th.equal(partition.index(actions), index)
    assert (actions >= partition.edges[index]).all()
    assert (actions < partition.edges[index + 1]).all()
    # Uniform within the interval: the offset from the lower edge, in units of the interval width, has mean 1/2.
    offsets = (actions - partition.edges[index]) * (n_intervals / 2)
    assert abs(offsets.mean() - 0.5) < 4 * math.sqrt(1 / 12 / offsets.numel())


def test_a_fixed_generator_gives_the_same_draws():
    first = boltzmann_interval_draw(repeated(ADVANTAGES, 100), EDGES, 1.0, generator(7))
    second = boltzmann_interval_draw(repeated(ADVANTAGES, 100), EDGES, 1.0, generator(7))
    assert all(th.equal(a, b) for a, b in zip(first, second, strict=True))


@pytest.mark.parametrize("probability", [0.0, 0.3, 1.0])
def test_each_component_is_replaced_with_the_probability(probability):
    actions = th.full((N_DRAWS, 2), 0.9, dtype=th.float64)  # in the last interval, which the advantages disfavour
    advantages = repeated(th.tensor([[5.0, 0.0, 0.0, 0.0, -5.0]] * 2))
    calls = []

    def advantages_of_the_state():
        calls.append(1)
        return advantages

    explored = explore_from_advantages(actions, advantages_of_the_state, EDGES, probability, 1e-3, generator())
    assert len(calls) == (probability > 0)  # no critic pass when nothing is drawn
    assert explored.dtype == actions.dtype
    replaced = explored != actions
    # Replaced components are draws from the best interval; the others are the given actions, untouched.
    assert (explored[replaced] < -0.6).all()
    assert (explored[~replaced] == 0.9).all()
    share = replaced.double().mean(dim=0)
    tolerance = 4 * math.sqrt(probability * (1 - probability) / N_DRAWS)
    assert ((share - probability).abs() <= tolerance).all()
    if 0 < probability < 1:
        # Per component: some samples have one dimension replaced and not the other.
        assert (replaced[:, 0] != replaced[:, 1]).any()


# The model: a tiny env with a 3-D action space of different bounds per dimension.
LOW = np.array([-1.0, -2.0, 0.0], dtype=np.float32)
HIGH = np.array([1.0, 2.0, 5.0], dtype=np.float32)


class ThreeDimensionalEnv(gym.Env):
    """A 2-D random-walk observation, a 3-D action, the reward minus the squared scaled action."""

    observation_space = spaces.Box(-np.inf, np.inf, (2,), np.float32)
    action_space = spaces.Box(LOW, HIGH, dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self._steps = 0
        return self.np_random.normal(size=2).astype(np.float32), {}

    def step(self, action):
        self._steps += 1
        scaled = 2 * (np.asarray(action) - LOW) / (HIGH - LOW) - 1
        observation = self.np_random.normal(size=2).astype(np.float32)
        return observation, -float(np.square(scaled).sum()), False, self._steps >= 20, {}


def make_model(env=None, **kwargs):
    options = dict(
        policy_kwargs=dict(net_arch=[16], n_intervals=N_INTERVALS),
        learning_starts=50,
        batch_size=16,
        buffer_size=2000,
        action_noise=EpsilonGaussianNoise(np.zeros(3), 0.2 * np.ones(3), decay_steps=100),
        seed=0,
    )
    options.update(kwargs)
    return ADC("MlpPolicy", env or ThreeDimensionalEnv(), **options)


def trained(steps=150, **kwargs):
    """The actions stored by ``learn`` (scaled) and the parameters it leaves."""
    model = make_model(**kwargs).learn(steps)
    actions = model.replay_buffer.actions[:steps, 0].copy()
    return model, actions, [p.detach().clone() for p in model.policy.parameters()]


# A constructed critic: no hidden layer, no value, and in action dimension d the advantage b_d P_1(a) - P_2(a), with
# its maximum at b_d / 3, in interval BEST[d]; the actor's action is a constant, 0.7 in every dimension (interval 4).
BIASES = [-2.4, 0.0, 1.2]
BEST = [0, 2, 3]
ACTOR_ACTION = 0.7


def constructed_model(**kwargs):
    model = make_model(
        policy_kwargs=dict(net_arch=dict(pi=[4], qf=[]), n_intervals=N_INTERVALS, basis_degree=2),
        learning_starts=0,
        gradient_steps=0,  # no update: the constructed networks stay as they are
        action_noise=None,
        **kwargs,
    )
    heads = model.critic.q_networks[0].heads  # outputs [V | c_{1,1}, c_{1,2} | c_{2,1}, c_{2,2} | c_{3,1}, c_{3,2}]
    last_actor_layer = model.actor.mu[-2]
    with th.no_grad():
        heads.weight.zero_()
        heads.bias.copy_(th.tensor([0.0, BIASES[0], -1.0, BIASES[1], -1.0, BIASES[2], -1.0]))
        last_actor_layer.weight.zero_()
        last_actor_layer.bias.fill_(math.atanh(ACTOR_ACTION))
    return model


def test_the_constructed_critic():
    model = constructed_model()
    advantages = model.critic.interval_advantages(th.zeros(4, 2))
    assert advantages.shape == (4, 3, N_INTERVALS)
    assert th.equal(advantages.argmax(dim=-1), th.tensor([BEST] * 4))
    # The advantages the exploration draws from are the critic's: its Q differs between centres by their difference.
    centres = model.critic.partition.centres
    obs = th.zeros(N_INTERVALS, 2)
    q_along_first = model.critic.q1_forward(obs, along_first_dimension(centres)).squeeze(1)
    th.testing.assert_close(q_along_first - q_along_first[0], advantages[0, 0] - advantages[0, 0, 0])


def along_first_dimension(centres):
    """The interval centres in the first action dimension, the other two at 0."""
    return th.stack([centres, th.zeros_like(centres), th.zeros_like(centres)], dim=1)


def test_exploration_draws_each_dimension_from_its_own_advantages():
    steps = 200
    model = constructed_model(interval_exploration=1.0, interval_temperature=1e-4).learn(steps)
    actions = th.as_tensor(model.replay_buffer.actions[:steps, 0])
    # Every component is in its own dimension's best interval, uniformly spread within it.
    assert th.equal(model.critic.partition.index(actions), th.tensor([BEST] * steps))
    assert len(th.unique(actions[:, 0])) == steps
    # The environment got the same actions in its own bounds.
    unscaled = model.policy.unscale_action(actions.numpy())
    assert ((unscaled >= LOW) & (unscaled <= HIGH)).all()


def test_without_a_draw_the_actor_acts():
    steps = 400
    model = constructed_model(interval_exploration=0.5, interval_temperature=1e-4).learn(steps)
    actions = th.as_tensor(model.replay_buffer.actions[:steps, 0])
    from_actor = (actions - ACTOR_ACTION).abs() < 1e-6
    drawn = model.critic.partition.index(actions) == th.tensor(BEST)
    assert (from_actor ^ drawn).all()
    share = drawn.double().mean(dim=0)
    assert ((share - 0.5).abs() <= 4 * math.sqrt(0.25 / steps)).all()
    assert (drawn[:, 0] != drawn[:, 1]).any()  # per dimension, not per step


def test_each_environment_of_a_vectorised_env_draws_its_own_actions():
    steps = 60
    env = make_vec_env(ThreeDimensionalEnv, n_envs=2, seed=0)
    model = constructed_model(env=env, interval_exploration=1.0, interval_temperature=1e-4).learn(steps)
    actions = th.as_tensor(model.replay_buffer.actions[: steps // 2])  # (steps per env, n_envs, action_dim)
    assert th.equal(model.critic.partition.index(actions), th.tensor([[BEST] * 2] * (steps // 2)))
    assert not th.equal(actions[:, 0], actions[:, 1])


def test_deterministic_predictions_do_not_explore():
    model = constructed_model(interval_exploration=1.0)
    action, _ = model.predict(np.zeros((1, 2), np.float32), deterministic=True)
    np.testing.assert_allclose(model.policy.scale_action(action), ACTOR_ACTION, rtol=1e-5)


def test_warm_up_stays_uniform():
    learning_starts = 50
    _, plain, _ = trained(steps=learning_starts + 20)
    _, explored, _ = trained(steps=learning_starts + 20, interval_exploration=1.0)
    assert np.array_equal(plain[:learning_starts], explored[:learning_starts])
    assert not np.array_equal(plain[learning_starts:], explored[learning_starts:])


def test_zero_probability_is_sb3s_exploration_bit_for_bit(monkeypatch):
    _, actions, parameters = trained(interval_exploration=0.0, interval_temperature=0.01)
    with monkeypatch.context() as patch:
        patch.setattr(ADC, "_sample_action", TD3._sample_action)  # SB3's OffPolicyAlgorithm._sample_action
        _, sb3_actions, sb3_parameters = trained()
    assert np.array_equal(actions, sb3_actions)
    assert all(th.equal(a, b) for a, b in zip(parameters, sb3_parameters, strict=True))
    # The comparison is not vacuous: a non-zero probability changes the actions and the parameters.
    _, explored_actions, explored_parameters = trained(interval_exploration=0.2)
    assert not np.array_equal(actions, explored_actions)
    assert not all(th.equal(a, b) for a, b in zip(parameters, explored_parameters, strict=True))


def test_a_fixed_seed_reproduces_the_exploration():
    _, first, first_parameters = trained(interval_exploration=0.5)
    _, second, second_parameters = trained(interval_exploration=0.5)
    assert np.array_equal(first, second)
    assert all(th.equal(a, b) for a, b in zip(first_parameters, second_parameters, strict=True))


@pytest.mark.parametrize(
    ("name", "value", "accepted"),
    [
        ("interval_exploration", 1.5, r"a number in \[0, 1\]"),
        ("interval_exploration", -0.1, r"a number in \[0, 1\]"),
        ("interval_exploration", float("nan"), r"a number in \[0, 1\]"),
        ("interval_exploration", True, r"a number in \[0, 1\]"),
        ("interval_exploration", "0.5", r"a number in \[0, 1\]"),
        ("interval_temperature", 0.0, "a finite number > 0"),
        ("interval_temperature", -1.0, "a finite number > 0"),
        ("interval_temperature", float("inf"), "a finite number > 0"),
        ("interval_temperature", None, "a finite number > 0"),
    ],
)
def test_invalid_values_are_refused_naming_the_parameter(name, value, accepted):
    with pytest.raises(ValueError, match=rf"`{name}` must be {accepted}, got"):
        ADC("MlpPolicy", "Pendulum-v1", **{name: value})


@pytest.mark.parametrize("design", NON_GREEDY_DESIGNS)
def test_exploration_needs_a_one_pass_design(design):
    policy_kwargs = dict(critic_design=design, net_arch=[8])
    with pytest.raises(ValueError, match=rf"`interval_exploration` needs .* critic_design='{design}'"):
        ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=policy_kwargs, interval_exploration=0.5)
    ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=policy_kwargs, interval_exploration=0.0)
    critic = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=policy_kwargs).critic
    with pytest.raises(ValueError, match=r"`interval_advantages` needs critic_design in \('legendre',\)"):
        critic.interval_advantages(th.zeros(1, 3))
