"""ADC's training step: Algorithm 1 on SB3's TD3 machinery, separate learning rates, diagnostics."""

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3.common.logger import configure
from stable_baselines3.common.utils import LinearSchedule

from sb3_adc import ADC, EpsilonGaussianNoise
from sb3_adc.adc.policies import ADCPolicy

TINY = dict(net_arch=[16], n_intervals=8)


def make_model(env="Pendulum-v1", **kwargs):
    options = dict(policy_kwargs=TINY, learning_starts=50, batch_size=16, buffer_size=2000, seed=0)
    options.update(kwargs)
    return ADC("MlpPolicy", env, **options)


def parameters(module):
    return [p.detach().clone() for p in module.parameters()]


def test_defaults_follow_the_paper_but_for_the_critic_design():
    model = make_model(policy_kwargs=None)
    assert isinstance(model.policy, ADCPolicy)
    assert model.policy.critic.n_critics == 1  # one dueling critic
    assert model.policy_delay == 1  # actor updated at every gradient step
    assert model.target_policy_noise == 0.0  # no target-policy smoothing
    assert 0 < model.tau < 1  # soft target updates
    assert model.critic.aggregation == "mean"  # Eq. 13-14
    assert model.critic.advantage_interpolation == "none"
    assert model.critic.n_intervals == 100
    # The critic study's best design (docs/results); the paper's form is critic_design="paper".
    assert model.critic.critic_design == "legendre"


def test_one_train_step_changes_actor_critic_and_targets_softly():
    model = make_model(tau=0.1)
    model.learn(60)  # fills the buffer past learning_starts
    actor, critic, critic_target = parameters(model.actor), parameters(model.critic), parameters(model.critic_target)
    model.train(gradient_steps=1, batch_size=16)
    assert any(not th.equal(a, b) for a, b in zip(actor, parameters(model.actor), strict=True))
    assert any(not th.equal(a, b) for a, b in zip(critic, parameters(model.critic), strict=True))
    # Soft update: theta' <- tau * theta + (1 - tau) * theta'
    for old_target, new_online, new_target in zip(
        critic_target, parameters(model.critic), parameters(model.critic_target), strict=True
    ):
        th.testing.assert_close(new_target, 0.1 * new_online + 0.9 * old_target)


def test_actor_gradient_flows_through_the_dueling_critic():
    model = make_model()
    model.learn(60)
    observations = th.as_tensor(model.replay_buffer.observations[:16, 0])
    model.actor.optimizer.zero_grad()
    loss = -model.critic.q1_forward(observations, model.actor(observations)).mean()
    loss.backward()
    gradients = [p.grad for p in model.actor.parameters()]
    assert all(g is not None and th.any(g != 0) for g in gradients)


def test_separate_learning_rates_in_the_optimizers():
    model = make_model(learning_rate=3e-4, critic_learning_rate=7e-4)
    assert model.actor.optimizer.param_groups[0]["lr"] == pytest.approx(3e-4)
    assert model.critic.optimizer.param_groups[0]["lr"] == pytest.approx(7e-4)
    model.learn(100)
    assert model.actor.optimizer.param_groups[0]["lr"] == pytest.approx(3e-4)
    assert model.critic.optimizer.param_groups[0]["lr"] == pytest.approx(7e-4)


def test_default_critic_rate_is_twice_the_actor_rate_along_a_schedule():
    model = make_model(learning_rate=LinearSchedule(1e-3, 1e-4, 1.0))
    assert model.critic.optimizer.param_groups[0]["lr"] == pytest.approx(2e-3)
    model.learn(200)
    actor_lr = model.actor.optimizer.param_groups[0]["lr"]
    critic_lr = model.critic.optimizer.param_groups[0]["lr"]
    assert actor_lr < 1e-3  # the schedule moved
    assert critic_lr == pytest.approx(2 * actor_lr)


def test_critic_rate_schedule_is_followed():
    model = make_model(learning_rate=1e-3, critic_learning_rate=LinearSchedule(1e-2, 0.0, 1.0))
    model.learn(200)
    expected = model.critic_lr_schedule(model._current_progress_remaining)
    assert model.critic.optimizer.param_groups[0]["lr"] == pytest.approx(expected)
    assert model.actor.optimizer.param_groups[0]["lr"] == pytest.approx(1e-3)


def test_training_logs_rates_losses_and_critic_diagnostics(tmp_path):
    model = make_model(learning_rate=1e-3, critic_learning_rate=5e-3)
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(250, log_interval=1)
    logged = model.logger.name_to_value
    assert logged["train/learning_rate"] == pytest.approx(1e-3)
    assert logged["train/critic_learning_rate"] == pytest.approx(5e-3)
    for key in ("train/critic_loss", "train/actor_loss", "train/value_mean", "train/advantage_std"):
        assert np.isfinite(logged[key]), key
    assert logged["train/advantage_std"] >= 0
    header = (tmp_path / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"train/value_mean", "train/advantage_std", "train/critic_learning_rate"} <= set(header)


def test_twin_critics_with_target_policy_smoothing():
    model = make_model(policy_kwargs=dict(TINY, n_critics=2), target_policy_noise=0.2, target_noise_clip=0.5, policy_delay=2)
    model.learn(150)
    assert len(model.critic(th.zeros(3, 3), th.zeros(3, 1))) == 2
    assert model._n_updates > 0


@pytest.mark.parametrize("aggregation", ["mean", "max"])
@pytest.mark.parametrize("interpolation", ["none", "linear"])
def test_every_paper_critic_variant_trains(aggregation, interpolation):
    model = make_model(
        policy_kwargs=dict(TINY, critic_design="paper", aggregation=aggregation, advantage_interpolation=interpolation)
    )
    model.learn(120)
    assert model._n_updates > 0
    assert all(th.all(th.isfinite(p)) for p in model.policy.parameters())


class TwoDimensionalAction(gym.ActionWrapper):
    """Pendulum with a 2-D action space; the env applies the first dimension and ignores the second."""

    def __init__(self, env):
        super().__init__(env)
        self.action_space = spaces.Box(-2.0, 2.0, (2,), np.float32)

    def action(self, action):
        return action[:1]


@pytest.mark.parametrize("design", ["paper", "legendre"])
def test_multidimensional_actions_factorise_the_advantage(design):
    model = make_model(env=TwoDimensionalAction(gym.make("Pendulum-v1")), policy_kwargs=dict(TINY, critic_design=design))
    model.learn(100)
    _, advantages, index = model.critic.decompose(th.zeros(4, 3), th.zeros(4, 2))
    assert advantages.shape == (4, 2, 8)
    assert index.shape == (4, 2)


def test_n_step_returns_train():
    model = make_model(n_steps=3)
    model.learn(150)
    assert model._n_updates > 0
    sample = model.replay_buffer.sample(8)
    assert sample.discounts is not None


def test_epsilon_noise_decays_during_learning():
    noise = EpsilonGaussianNoise(np.zeros(1), np.full(1, 0.3), decay_steps=100)
    model = make_model(action_noise=noise)
    model.learn(200)
    # SB3 calls the noise once per environment step, warm-up included: 200 calls, past the decay.
    assert model.action_noise.n_calls == 200
    assert model.action_noise.epsilon == 0.0


def test_same_seed_same_training():
    first = make_model(seed=3)
    first.learn(120)
    second = make_model(seed=3)
    second.learn(120)
    for a, b in zip(parameters(first.policy), parameters(second.policy), strict=True):
        assert th.equal(a, b)


def test_tensorboard_run_is_named_adc(tmp_path):
    model = make_model(tensorboard_log=str(tmp_path))
    model.learn(60)
    assert [p.name for p in tmp_path.iterdir()] == ["ADC_1"]
