"""The critic designs of DuelingIntervalCritic: the dueling identity, dQ/da, state-only value, save/load, errors."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from numpy.polynomial import legendre
from stable_baselines3.common.torch_layers import create_mlp
from stable_baselines3.common.utils import ConstantSchedule
from stable_baselines3.td3.policies import TD3Policy
from torch import nn

from sb3_adc import ADC
from sb3_adc.adc.designs import NetworkSpec
from sb3_adc.adc.legendre import MONOMIAL_MAX_DEGREE, LegendreAdvantageNetwork, legendre_basis, legendre_monomial_matrix
from sb3_adc.adc.policies import CRITIC_DESIGNS, DEFAULT_BASIS_DEGREE, ADCPolicy, validate_critic_options
from sb3_adc.config import HyperparamsError, resolve_entry

NEW_DESIGNS = ["state_value", "legendre", "action_network"]


def make_critic(design, action_dim=1, n_intervals=10, **kwargs):
    observation_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
    action_space = spaces.Box(-2.0, 2.0, (action_dim,), np.float32)
    kwargs.setdefault("net_arch", [16])
    policy = ADCPolicy(
        observation_space,
        action_space,
        ConstantSchedule(1e-3),
        n_intervals=n_intervals,
        critic_design=design,
        **kwargs,
    )
    return policy.critic


def batch(action_dim=1, size=8, seed=0):
    generator = th.Generator().manual_seed(seed)
    obs = th.rand(size, 3, generator=generator) * 2 - 1
    actions = th.rand(size, action_dim, generator=generator) * 2 - 1
    return obs, actions


def centres(n):
    return (th.arange(n) + 0.5) * 2 / n - 1


@pytest.mark.parametrize("n_critics", [1, 2])
@pytest.mark.parametrize("action_dim", [1, 2])
@pytest.mark.parametrize("design", CRITIC_DESIGNS)
def test_every_design_has_the_critic_contract(design, action_dim, n_critics):
    critic = make_critic(design, action_dim=action_dim, n_critics=n_critics, value_net_arch=[8], advantage_net_arch=[8])
    obs, actions = batch(action_dim)
    q_values = critic(obs, actions)
    assert len(q_values) == n_critics
    assert all(q.shape == (8, 1) for q in q_values)
    th.testing.assert_close(critic.q1_forward(obs, actions), q_values[0])
    value, advantages, index = critic.decompose(obs, actions)
    branches = 1 if design == "action_network" else action_dim
    assert value.shape == (8, 1)
    assert advantages.shape == (8, branches, 10)
    assert index.shape == (8, action_dim)


@pytest.mark.parametrize("design", NEW_DESIGNS)
def test_value_stream_reads_the_state_only(design):
    critic = make_critic(design)
    obs, actions = batch()
    value, _, _ = critic.decompose(obs, actions)
    value_other, _, _ = critic.decompose(obs, -actions)
    th.testing.assert_close(value, value_other)


def test_paper_value_stream_depends_on_the_action():
    critic = make_critic("paper", value_net_arch=[8])
    obs, actions = batch()
    assert not th.allclose(critic.decompose(obs, actions)[0], critic.decompose(obs, -actions)[0])


# Degrees 3 and 8 take the monomial path of the centred basis, 12 Bonnet's recursion (MONOMIAL_MAX_DEGREE).
# Without hidden head layers the value and the coefficients are the outputs of one layer; with them, two heads.
@pytest.mark.parametrize("basis_degree", [3, MONOMIAL_MAX_DEGREE, 12])
@pytest.mark.parametrize("aggregation", ["mean", "max"])
@pytest.mark.parametrize("action_dim", [1, 2])
@pytest.mark.parametrize("head_arch", [None, [8]])
def test_legendre_q_is_value_plus_polynomial_advantage_centred_over_the_centres(
    action_dim, aggregation, basis_degree, head_arch
):
    critic = make_critic(
        "legendre",
        action_dim=action_dim,
        aggregation=aggregation,
        basis_degree=basis_degree,
        value_net_arch=head_arch,
        advantage_net_arch=head_arch,
    )
    assert critic.q_networks[0].fused_heads == (head_arch is None)
    network = critic.q_networks[0]
    obs, actions = batch(action_dim)
    features = critic.extract_features(obs, critic.features_extractor)
    value, coefficients = network._heads(features)
    # The reference evaluates the Legendre series with NumPy: sum_k c_k P_k, k = 1..degree (no constant term).
    expected = value.detach().numpy().copy()
    grid = centres(10).numpy()
    for d in range(action_dim):
        for i in range(8):
            series = np.concatenate([[0.0], coefficients[i, d].detach().numpy()])
            at_centres = legendre.legval(grid, series)
            baseline = at_centres.mean() if aggregation == "mean" else at_centres.max()
            expected[i, 0] += legendre.legval(actions[i, d].item(), series) - baseline
    np.testing.assert_allclose(critic(obs, actions)[0].detach().numpy(), expected, rtol=1e-5, atol=1e-5)
    # decompose gives the advantages at the interval centres, so Eq. 13-14 holds on them too.
    _, advantages, _ = critic.decompose(obs, actions)
    np.testing.assert_allclose(
        advantages[0, 0].detach().numpy(),
        legendre.legval(grid, np.concatenate([[0.0], coefficients[0, 0].detach().numpy()])),
        rtol=1e-5,
        atol=1e-6,
    )


def test_legendre_fused_heads_draw_the_initial_critic_of_two_separate_heads():
    # One layer holds the value head's row, then the coefficient head's, drawn in that order as two separate
    # layers would be: a seed gives the same initial critic either way.
    th.manual_seed(0)
    network = LegendreAdvantageNetwork(NetworkSpec(3, 2, 10, [16], [], [], nn.ReLU, "mean", basis_degree=4))
    th.manual_seed(0)
    trunk = nn.Sequential(*create_mlp(3, -1, [16], nn.ReLU))
    value_head, coefficient_head = nn.Linear(16, 1), nn.Linear(16, 2 * 4)
    assert th.equal(network.trunk[0].weight, trunk[0].weight)
    assert th.equal(network.heads.weight, th.cat([value_head.weight, coefficient_head.weight]))
    assert th.equal(network.heads.bias, th.cat([value_head.bias, coefficient_head.bias]))


def test_legendre_critic_has_as_many_parameter_tensors_as_ddpg_critic():
    # The optimiser and the target update cost per parameter tensor: the default critic matches DDPG's count.
    observation_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
    action_space = spaces.Box(-2.0, 2.0, (2,), np.float32)
    ddpg = TD3Policy(observation_space, action_space, ConstantSchedule(1e-3), net_arch=[16, 16], n_critics=1)
    adc = make_critic("legendre", action_dim=2, net_arch=[16, 16])
    assert len(list(adc.parameters())) == len(list(ddpg.critic.parameters())) == 6


@pytest.mark.parametrize("degree", range(1, MONOMIAL_MAX_DEGREE + 1))
def test_legendre_monomial_matrix_gives_the_legendre_polynomials_without_their_constants(degree):
    x = np.linspace(-1, 1, 9)
    powers = x[:, None] ** np.arange(1, degree + 1)
    basis = powers @ legendre_monomial_matrix(degree).double().numpy()
    for k in range(1, degree + 1):
        expected = legendre.legval(x, [0] * k + [1]) - legendre.legval(0.0, [0] * k + [1])
        np.testing.assert_allclose(basis[:, k - 1], expected, atol=1e-6)


def test_legendre_basis_matches_numpy():
    x = th.linspace(-1, 1, 7, dtype=th.float64)
    basis = legendre_basis(x, 5)
    for k in range(1, 6):
        np.testing.assert_allclose(basis[:, k - 1].numpy(), legendre.legval(x.numpy(), [0] * k + [1]), atol=1e-12)


@pytest.mark.parametrize("aggregation", ["mean", "max"])
@pytest.mark.parametrize("action_dim", [1, 2])
@pytest.mark.parametrize("design", ["state_value", "action_network"])
def test_q_is_value_plus_advantage_centred_on_the_intervals(design, action_dim, aggregation):
    critic = make_critic(design, action_dim=action_dim, aggregation=aggregation)
    obs, actions = batch(action_dim)
    value, advantages, index = critic.decompose(obs, actions)
    network = critic.q_networks[0]
    if design == "state_value":
        selected = advantages.gather(-1, index.unsqueeze(-1)).squeeze(-1)
    else:
        selected = network.advantage_net(th.cat([obs, actions], dim=1))
    baseline = advantages.mean(-1) if aggregation == "mean" else advantages.amax(-1)
    th.testing.assert_close(critic(obs, actions)[0], value + (selected - baseline).sum(-1, keepdim=True))


def test_action_network_baseline_covers_every_interval_centre_in_every_dimension():
    network = make_critic("action_network", action_dim=3, n_intervals=6).q_networks[0]
    for d in range(3):
        th.testing.assert_close(network.centre_actions[:, d].sort().values, centres(6))


@pytest.mark.parametrize("design", ["legendre", "action_network"])
def test_smooth_designs_are_continuous_across_interval_edges_and_the_paper_form_is_not(design):
    # An interval edge of 10 intervals sits at 0.2; the paper form switches advantage output there.
    obs = batch(size=16)[0]
    below, above = th.full((16, 1), 0.2 - 1e-5), th.full((16, 1), 0.2 + 1e-5)
    smooth = make_critic(design)
    assert (smooth.q1_forward(obs, above) - smooth.q1_forward(obs, below)).abs().max() < 1e-3
    paper = make_critic("paper")
    assert (paper.q1_forward(obs, above) - paper.q1_forward(obs, below)).abs().max() > 1e-3


def test_legendre_action_gradient_is_the_derivative_of_the_polynomial():
    critic = make_critic("legendre", basis_degree=4)
    obs, actions = batch()
    actions.requires_grad_(True)
    (gradient,) = th.autograd.grad(critic.q1_forward(obs, actions).sum(), actions)
    features = critic.extract_features(obs, critic.features_extractor)
    _, coefficients = critic.q_networks[0]._heads(features)
    for i in range(8):
        series = np.concatenate([[0.0], coefficients[i, 0].detach().numpy()])
        expected = legendre.legval(actions[i, 0].item(), legendre.legder(series))
        assert gradient[i, 0].item() == pytest.approx(expected, rel=1e-4, abs=1e-6)


@pytest.mark.parametrize("design", CRITIC_DESIGNS)
def test_action_gradient_matches_finite_differences(design):
    # A fixed initialisation: with weights drawn from whatever RNG state earlier tests left, a ReLU kink can
    # fall within the float32 finite-difference step of a test point.
    th.manual_seed(0)
    critic = make_critic(design, n_intervals=10)
    obs, _ = batch(size=4)
    # Points inside intervals, away from their edges and from ReLU kinks, where every design is differentiable.
    actions = th.tensor([[-0.55], [-0.05], [0.35], [0.75]], requires_grad=True)
    (gradient,) = th.autograd.grad(critic.q1_forward(obs, actions).sum(), actions)
    step = 1e-3
    numeric = (critic.q1_forward(obs, actions + step) - critic.q1_forward(obs, actions - step)) / (2 * step)
    th.testing.assert_close(gradient, numeric.detach(), rtol=1e-2, atol=1e-4)


def test_every_sample_trains_every_interval_advantage_of_the_legendre_design():
    critic = make_critic("legendre")
    obs, _ = batch(size=32)
    actions = th.full((32, 1), 0.95)  # every action in the last interval
    _, before, _ = critic.decompose(obs, actions)
    optimizer = th.optim.SGD(critic.parameters(), lr=0.1)
    (critic.q1_forward(obs, actions) - 1.0).pow(2).mean().backward()
    optimizer.step()
    _, after, _ = critic.decompose(obs, actions)
    changed = (after - before).abs().mean(dim=0)[0]
    assert th.all(changed > 0)


# The interval baseline of the default "legendre" critic, mean_z P_k(centre_z), is the midpoint rule for the
# integral of P_k over [-1, 1], which is 0: at the shipped degree its largest term is P_4's, 4.154e-3 for 20
# intervals and 1.666e-4 for 100. docs/modules/adc.rst quotes these bounds.
@pytest.mark.parametrize(("n_intervals", "bound"), [(20, 4.2e-3), (100, 1.7e-4)])
def test_legendre_interval_baseline_is_nearly_zero(n_intervals, bound):
    grid = centres(n_intervals).double()
    baseline = legendre_basis(grid, DEFAULT_BASIS_DEGREE).mean(dim=0)
    assert baseline.abs().max().item() < bound
    assert baseline.abs().max().item() > bound / 1.1  # the bound is the measured value, not a loose one


def test_legendre_n_intervals_only_shifts_q_by_a_small_state_constant():
    # Same weights, 20 or 100 intervals: Q(s, .) moves by -sum_k c_k(s) (b_k(20) - b_k(100)), a constant in the
    # action at most 4.0e-3 sum_k |c_k(s)| (|A(s, a)| <= sum_k |c_k(s)| on [-1, 1]); dQ/da is unchanged.
    th.manual_seed(0)
    coarse = make_critic("legendre", action_dim=2, n_intervals=20)
    fine = make_critic("legendre", action_dim=2, n_intervals=100)
    fine.q_networks[0].load_state_dict(coarse.q_networks[0].state_dict())  # the partition's edges differ
    obs, _ = batch(size=16)
    actions = th.rand(5, 16, 2, generator=th.Generator().manual_seed(1)) * 2 - 1
    actions.requires_grad_(True)
    shifts, gradients = [], []
    for critic in (coarse, fine):
        q = th.stack([critic.q1_forward(obs, actions[j]) for j in range(5)])  # (5, 16, 1)
        gradients.append(th.autograd.grad(q.sum(), actions)[0])
        shifts.append(q.detach())
    shift = shifts[0] - shifts[1]
    th.testing.assert_close(shift, shift[:1].expand_as(shift), rtol=0, atol=1e-6)
    th.testing.assert_close(gradients[0], gradients[1], rtol=1e-5, atol=1e-6)
    _, coefficients = coarse.q_networks[0]._heads(obs)
    scale = coefficients.abs().sum(dim=(1, 2)).detach()  # (16,)
    assert th.all(shift[0, :, 0].abs() <= 4.0e-3 * scale + 1e-6)
    assert shift.abs().max() > 0  # the baseline does change, just not by much


@pytest.mark.parametrize("design", CRITIC_DESIGNS)
def test_design_trains_saves_and_loads(tmp_path, design):
    model = ADC(
        "MlpPolicy",
        "Pendulum-v1",
        policy_kwargs=dict(net_arch=[16], n_intervals=8, critic_design=design, n_critics=2),
        target_policy_noise=0.2,
        target_noise_clip=0.5,
        learning_starts=50,
        batch_size=16,
        seed=0,
    )
    model.learn(120)
    model.save(tmp_path / "model")
    loaded = ADC.load(tmp_path / "model")
    assert loaded.critic.critic_design == design
    assert loaded.policy_kwargs["critic_design"] == design
    obs = th.as_tensor(np.random.default_rng(0).uniform(-1, 1, (5, 3)), dtype=th.float32)
    actions = th.zeros(5, 1)
    for original, restored in zip(model.critic(obs, actions), loaded.critic(obs, actions), strict=True):
        th.testing.assert_close(original, restored)


@pytest.mark.parametrize(
    ("options", "problem"),
    [
        (dict(critic_design="dueling"), r"`critic_design` must be one of \('paper', 'state_value', 'legendre'"),
        (dict(critic_design="legendre", advantage_interpolation="linear"), '`advantage_interpolation` must be "none"'),
        (dict(critic_design="legendre", basis_degree=0), r"`basis_degree` must be an integer in \[1, 16\]"),
        (dict(critic_design="legendre", basis_degree=True), "`basis_degree`"),
    ],
)
def test_invalid_design_options_name_the_parameter(options, problem):
    arguments = dict(critic_design="paper", n_intervals=10, aggregation="mean", advantage_interpolation="none", basis_degree=4)
    arguments.update(options)
    with pytest.raises(ValueError, match=problem):
        validate_critic_options(**arguments)
    with pytest.raises(ValueError, match=problem):
        make_critic(**{"design": arguments.pop("critic_design"), **arguments})


def test_hyperparameter_entries_accept_the_design_keys():
    entry = {"n_timesteps": 100, "policy": "MlpPolicy", "critic_design": "legendre", "basis_degree": 3}
    config = resolve_entry("adc", "Pendulum-v1", entry, "my.yml [Pendulum-v1]")
    assert config.model_kwargs["policy_kwargs"] == {"critic_design": "legendre", "basis_degree": 3}
    with pytest.raises(HyperparamsError, match="critic_design"):
        resolve_entry("adc", "Pendulum-v1", {**entry, "critic_design": "dueling"}, "my.yml [Pendulum-v1]")


def test_files_saved_before_critic_design_existed_load_with_the_paper_critic(tmp_path):
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[16], n_intervals=8, critic_design="paper"), seed=0)
    # A file of an earlier version: its policy_kwargs do not name the design, and its critic is the paper's.
    model.policy_kwargs = {key: value for key, value in model.policy_kwargs.items() if key != "critic_design"}
    model.save(tmp_path / "old")
    loaded = ADC.load(tmp_path / "old")
    assert loaded.critic.critic_design == "paper"
    with open(tmp_path / "old.zip", "rb") as stream:
        assert ADC.load(stream).critic.critic_design == "paper"


def test_the_default_design_is_recorded_in_the_saved_file(tmp_path):
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[16], n_intervals=8), seed=0)
    assert model.policy_kwargs["critic_design"] == model.critic.critic_design
    model.save(tmp_path / "new")
    assert ADC.load(tmp_path / "new").critic.critic_design == model.critic.critic_design
