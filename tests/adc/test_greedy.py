"""Greedy use of every interval at once: the critic's best grid point, greedy TD targets, greedy policy improvement."""

import math

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3.common.type_aliases import ReplayBufferSamples
from stable_baselines3.common.utils import ConstantSchedule

from sb3_adc import ADC
from sb3_adc.adc.policies import CRITIC_DESIGNS, GREEDY_CRITIC_DESIGNS, ADCPolicy

N_INTERVALS = 5
CENTRES = th.tensor([-0.8, -0.4, 0.0, 0.4, 0.8])
NON_GREEDY_DESIGNS = [design for design in CRITIC_DESIGNS if design not in GREEDY_CRITIC_DESIGNS]


class TwoDimensionalAction(gym.ActionWrapper):
    """Pendulum with a 2-D action space; the env applies the first dimension and ignores the second."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.action_space = spaces.Box(-2.0, 2.0, (2,), np.float32)

    def action(self, action: np.ndarray) -> np.ndarray:
        return action[:1]


def two_dimensional_env() -> gym.Env:
    return TwoDimensionalAction(gym.make("Pendulum-v1"))


def make_model(**kwargs):
    options = dict(
        policy_kwargs=dict(net_arch=[16], n_intervals=N_INTERVALS),
        learning_starts=50,
        batch_size=16,
        buffer_size=2000,
        seed=0,
    )
    options.update(kwargs)
    return ADC("MlpPolicy", two_dimensional_env(), **options)


def grid(n_dims=2):
    """Every point of the grid of interval centres, ``(N_INTERVALS ** n_dims, n_dims)``."""
    return th.cartesian_prod(*[CENTRES] * n_dims)


def brute_force_greedy(q_function, obs):
    """``argmax_z Q(s, z)`` and its value over the full Cartesian grid, one evaluation per grid point."""
    points = grid()
    with th.no_grad():
        values = th.cat([q_function(obs, point.expand(len(obs), 2)) for point in points], dim=1)
    best, index = values.max(dim=1)
    return points[index], best.unsqueeze(1)


def random_obs(size=64, seed=0):
    return th.randn(size, 3, generator=th.Generator().manual_seed(seed)) * 2


def perturb(module, scale, seed):
    generator = th.Generator().manual_seed(seed)
    with th.no_grad():
        for parameter in module.parameters():
            parameter.add_(th.randn(parameter.shape, generator=generator) * scale)


def test_the_grid_centres_are_the_interval_centres():
    model = make_model()
    th.testing.assert_close(model.critic.partition.centres, CENTRES)


@pytest.mark.parametrize("aggregation", ["mean", "max"])
@pytest.mark.parametrize(
    "network",
    [
        dict(),  # fused single-layer heads, monomial basis
        dict(value_net_arch=[8], advantage_net_arch=[8]),  # separate heads
        dict(basis_degree=10),  # Bonnet's recursion
    ],
)
@pytest.mark.parametrize("design", GREEDY_CRITIC_DESIGNS)
def test_greedy_action_is_the_best_point_of_the_whole_grid(design, network, aggregation):
    observation_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
    action_space = spaces.Box(-2.0, 2.0, (2,), np.float32)
    policy = ADCPolicy(
        observation_space,
        action_space,
        ConstantSchedule(1e-3),
        net_arch=[16],
        n_intervals=N_INTERVALS,
        critic_design=design,
        aggregation=aggregation,
        **network,
    )
    critic = policy.critic
    perturb(critic, 0.3, seed=1)  # larger coefficients than at initialisation: varied, well-separated optima
    obs = random_obs()
    action, value = critic.greedy_action(obs)
    expected_action, expected_value = brute_force_greedy(critic.q1_forward, obs)
    th.testing.assert_close(action, expected_action)
    th.testing.assert_close(value, expected_value)
    # The value is the Q-value of the critic at that action; with Eq. 11 (max), it is V(s).
    th.testing.assert_close(value, critic.q1_forward(obs, action).detach())
    if aggregation == "max":
        th.testing.assert_close(value, critic.decompose(obs, action)[0].detach())
    # A discriminating case: the best grid point differs between states and is off the diagonal somewhere.
    assert len(th.unique(action, dim=0)) >= 4
    assert (action[:, 0] != action[:, 1]).any()


@pytest.mark.parametrize("design", NON_GREEDY_DESIGNS)
def test_designs_whose_advantage_reads_the_action_have_no_one_pass_greedy_action(design):
    model = make_model(policy_kwargs=dict(net_arch=[16], n_intervals=N_INTERVALS, critic_design=design))
    with pytest.raises(ValueError, match=r"`greedy_action` needs critic_design in \('legendre',\)"):
        model.critic.greedy_action(random_obs(4))


def transitions(model, size=32, seed=0):
    generator = th.Generator().manual_seed(seed)
    return ReplayBufferSamples(
        observations=th.randn(size, 3, generator=generator),
        actions=th.rand(size, 2, generator=generator) * 2 - 1,
        next_observations=th.randn(size, 3, generator=generator) * 2,
        dones=(th.rand(size, 1, generator=generator) < 0.25).float(),
        rewards=th.randn(size, 1, generator=generator),
    )


def twin_model_with_distinct_targets(**kwargs):
    model = make_model(policy_kwargs=dict(net_arch=[16], n_intervals=N_INTERVALS, n_critics=2), **kwargs)
    perturb(model.critic, 0.3, seed=1)
    perturb(model.critic_target, 0.3, seed=2)  # the target critics differ from the online ones and each other
    return model


def test_greedy_target_with_mix_one_is_the_target_value_of_the_online_argmax():
    model = twin_model_with_distinct_targets(target_greedy_mix=1.0, gamma=0.9)
    batch = transitions(model)
    greedy, _ = brute_force_greedy(model.critic.q1_forward, batch.next_observations)
    with th.no_grad():
        first, second = model.critic_target(batch.next_observations, greedy)
    expected = batch.rewards + 0.9 * (1 - batch.dones) * th.minimum(first, second)
    th.testing.assert_close(model.target_q_values(batch), expected)
    # Double-Q: the online critic chooses z*, which is not the target critic's own choice on every state.
    target_greedy, _ = brute_force_greedy(model.critic_target.q1_forward, batch.next_observations)
    assert (target_greedy != greedy).any()
    # Terminal transitions bootstrap nothing.
    assert batch.dones.sum() > 0
    done = batch.dones.squeeze(1) == 1
    th.testing.assert_close(model.target_q_values(batch)[done], batch.rewards[done])


@pytest.mark.parametrize("mix", [0.0, 0.3])
def test_greedy_target_mixes_the_policy_and_greedy_values(mix):
    model = twin_model_with_distinct_targets(target_greedy_mix=mix, gamma=0.9)
    batch = transitions(model)
    with th.no_grad():
        policy_value = th.minimum(*model.critic_target(batch.next_observations, model.actor_target(batch.next_observations)))
        greedy, _ = brute_force_greedy(model.critic.q1_forward, batch.next_observations)
        greedy_value = th.minimum(*model.critic_target(batch.next_observations, greedy))
    expected = batch.rewards + 0.9 * (1 - batch.dones) * ((1 - mix) * policy_value + mix * greedy_value)
    th.testing.assert_close(model.target_q_values(batch), expected)


def test_zero_mix_and_weight_reproduce_the_plain_update():
    def trained(**kwargs):
        model = make_model(policy_kwargs=dict(net_arch=[16], n_critics=2), target_policy_noise=0.2, **kwargs)
        model.target_noise_clip = 0.5
        model.learn(120)
        return [p.detach().clone() for p in model.policy.parameters()]

    plain = trained()
    assert all(th.equal(a, b) for a, b in zip(plain, trained(target_greedy_mix=0.0, actor_greedy_weight=0.0), strict=True))
    # Either option changes the update (the comparison above is not vacuous).
    assert not all(th.equal(a, b) for a, b in zip(plain, trained(target_greedy_mix=0.5), strict=True))
    assert not all(th.equal(a, b) for a, b in zip(plain, trained(actor_greedy_weight=1.0), strict=True))


# Greedy policy improvement, on a constructed critic: no hidden layer, no value, and in each action dimension the
# advantage c_1(s) P_1(a) - P_2(a) = c_1(s) a - (3 a^2 - 1) / 2, concave with its maximum at a = c_1(s) / 3, where
# c_1(s) is the first observation. The actor's action is a constant, 0.3 in both dimensions, which no interval
# centre equals: on state A (c_1 = 0.9) the actor's action is the optimum, so the best centre (0.4) is worse; on
# state B (c_1 = -2.4, optimum -0.8) the best centre, (-0.8, -0.8), beats it.
ACTOR_ACTION = 0.3
STATE_A = [0.9, 0.0, 0.0]
STATE_B = [-2.4, 0.0, 0.0]


def constructed_model(actor_greedy_weight):
    model = make_model(
        policy_kwargs=dict(net_arch=dict(pi=[4], qf=[]), n_intervals=N_INTERVALS, basis_degree=2),
        actor_greedy_weight=actor_greedy_weight,
    )
    heads = model.critic.q_networks[0].heads  # outputs [V | c_{1,1}, c_{1,2} | c_{2,1}, c_{2,2}]
    last_actor_layer = model.actor.mu[-2]
    with th.no_grad():
        heads.weight.zero_()
        heads.bias.copy_(th.tensor([0.0, 0.0, -1.0, 0.0, -1.0]))
        heads.weight[1, 0] = heads.weight[3, 0] = 1.0
        last_actor_layer.weight.zero_()
        last_actor_layer.bias.fill_(math.atanh(ACTOR_ACTION))
    return model


def gradients(model, obs):
    model.policy.zero_grad(set_to_none=False)
    model.actor_loss(obs).backward()
    return (
        [p.grad.clone() for p in model.actor.parameters()],
        [p.grad.clone() for p in model.critic.parameters()],
    )


def test_the_constructed_case():
    model = constructed_model(actor_greedy_weight=1.0)
    obs = th.tensor([STATE_A, STATE_B])
    greedy, greedy_value = model.critic.greedy_action(obs)
    th.testing.assert_close(greedy, th.tensor([[0.4, 0.4], [-0.8, -0.8]]))
    actor_value = model.critic.q1_forward(obs, model.actor(obs)).detach()
    th.testing.assert_close(model.actor(obs).detach(), th.full((2, 2), ACTOR_ACTION))
    assert greedy_value[0] < actor_value[0]
    assert greedy_value[1] > actor_value[1]


@pytest.mark.parametrize(
    ("states", "pulled_share"),
    [([STATE_A], 0.0), ([STATE_B], 1.0), ([STATE_A, STATE_B], 0.5)],
)
def test_greedy_pull_acts_only_where_the_best_centre_beats_the_actor(states, pulled_share):
    weight = 0.7
    obs = th.tensor(states)
    model = constructed_model(actor_greedy_weight=weight)
    actor_grads, critic_grads = gradients(model, obs)
    model.actor_greedy_weight = 0.0
    plain_actor_grads, plain_critic_grads = gradients(model, obs)
    # The critic gets no gradient from the pull.
    assert all(th.equal(a, b) for a, b in zip(critic_grads, plain_critic_grads, strict=True))
    # The actor's last bias b (pi = tanh(b)) gets w * share * d/db ||tanh(b) - z*||^2 = w * share * 2 (pi - z*)(1 - pi^2)
    # per dimension, with z* = -0.8 on state B; on state A, nothing.
    extra = [a - b for a, b in zip(actor_grads, plain_actor_grads, strict=True)]
    pull_on_b = weight * 2 * (ACTOR_ACTION + 0.8) * (1 - ACTOR_ACTION**2)
    th.testing.assert_close(extra[-1], th.full((2,), pulled_share * pull_on_b))
    # The other actor parameters are upstream of a zero last-layer weight: no gradient from either loss.
    assert all(th.count_nonzero(g) == 0 for g in extra[:-2])


@pytest.mark.parametrize(
    ("name", "value", "accepted"),
    [
        ("target_greedy_mix", 1.5, r"a number in \[0, 1\]"),
        ("target_greedy_mix", -0.1, r"a number in \[0, 1\]"),
        ("target_greedy_mix", float("nan"), r"a number in \[0, 1\]"),
        ("target_greedy_mix", True, r"a number in \[0, 1\]"),
        ("target_greedy_mix", "0.5", r"a number in \[0, 1\]"),
        ("actor_greedy_weight", -1.0, "a finite number >= 0"),
        ("actor_greedy_weight", float("inf"), "a finite number >= 0"),
        ("actor_greedy_weight", None, "a finite number >= 0"),
    ],
)
def test_invalid_values_are_refused_naming_the_parameter(name, value, accepted):
    with pytest.raises(ValueError, match=rf"`{name}` must be {accepted}, got"):
        ADC("MlpPolicy", "Pendulum-v1", **{name: value})


@pytest.mark.parametrize("name", ["target_greedy_mix", "actor_greedy_weight"])
@pytest.mark.parametrize("design", NON_GREEDY_DESIGNS)
def test_greedy_options_need_a_one_pass_design(design, name):
    with pytest.raises(ValueError, match=rf"`{name}` needs .* critic_design='{design}' .* in \('legendre',\) or {name}=0"):
        ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(critic_design=design, net_arch=[8]), **{name: 0.5})
    # Off, the design builds as before.
    ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(critic_design=design, net_arch=[8]), **{name: 0.0})


def test_save_and_load_keep_the_options(tmp_path):
    model = make_model(target_greedy_mix=0.25, actor_greedy_weight=0.125)
    model.save(tmp_path / "greedy.zip")
    loaded = ADC.load(tmp_path / "greedy.zip", env=two_dimensional_env())
    assert (loaded.target_greedy_mix, loaded.actor_greedy_weight) == (0.25, 0.125)
    batch = transitions(model)
    th.testing.assert_close(loaded.target_q_values(batch), model.target_q_values(batch))
