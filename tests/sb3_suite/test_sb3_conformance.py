"""Everything SB3 users rely on works with ADC unchanged."""

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import DDPG
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.envs import FakeImageEnv, SimpleMultiObsEnv
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from sb3_adc import ADC, EpsilonGaussianNoise
from sb3_adc.adc.policies import ADCPolicy, CnnPolicy, MultiInputPolicy

TINY = dict(net_arch=[16], n_intervals=8)
FAST = dict(learning_starts=50, batch_size=16, buffer_size=2000, seed=0)


def observations(env, n=5, seed=0):
    env.reset(seed=seed)
    return np.stack([env.observation_space.sample() for _ in range(n)])


def test_save_load_round_trip_gives_identical_predictions(tmp_path):
    model = ADC("MlpPolicy", "Pendulum-v1", learning_rate=2e-4, critic_learning_rate=6e-4, policy_kwargs=TINY, **FAST)
    model.learn(120)
    obs = observations(model.env.envs[0])
    before, _ = model.predict(obs, deterministic=True)
    model.save(tmp_path / "adc.zip")

    loaded = ADC.load(tmp_path / "adc.zip", env=gym.make("Pendulum-v1"))
    after, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(before, after)
    for original, restored in zip(model.policy.state_dict().values(), loaded.policy.state_dict().values(), strict=True):
        assert th.equal(original, restored)
    assert isinstance(loaded.policy, ADCPolicy)
    assert loaded.policy.n_intervals == 8
    assert loaded.critic_learning_rate == 6e-4
    assert loaded.actor.optimizer.param_groups[0]["lr"] == pytest.approx(2e-4)
    assert loaded.critic.optimizer.param_groups[0]["lr"] == pytest.approx(6e-4)
    # Training continues, with both rates kept.
    loaded.learn(60, reset_num_timesteps=False)
    assert loaded.num_timesteps == 180
    assert loaded.critic.optimizer.param_groups[0]["lr"] == pytest.approx(6e-4)
    assert loaded.actor.optimizer.param_groups[0]["lr"] == pytest.approx(2e-4)


def test_load_keeps_the_default_twice_actor_rate(tmp_path):
    model = ADC("MlpPolicy", "Pendulum-v1", learning_rate=3e-4, policy_kwargs=TINY, **FAST)
    model.save(tmp_path / "adc")
    loaded = ADC.load(tmp_path / "adc", env=gym.make("Pendulum-v1"))
    loaded.learn(80)
    assert loaded.critic.optimizer.param_groups[0]["lr"] == pytest.approx(6e-4)


def test_policy_alone_saves_and_loads(tmp_path):
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(TINY, aggregation="max"), **FAST)
    model.policy.save(tmp_path / "policy.pth")
    policy = ADCPolicy.load(tmp_path / "policy.pth")
    assert policy.critic.aggregation == "max"
    obs = observations(model.env.envs[0])
    np.testing.assert_array_equal(policy.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0])


def test_replay_buffer_round_trip(tmp_path):
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, **FAST)
    model.learn(100)
    model.save_replay_buffer(tmp_path / "buffer")
    fresh = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, **FAST)
    fresh.load_replay_buffer(tmp_path / "buffer")
    assert fresh.replay_buffer.size() == 100
    np.testing.assert_array_equal(fresh.replay_buffer.actions[:100], model.replay_buffer.actions[:100])


def test_action_noise_state_survives_save_and_load(tmp_path):
    noise = EpsilonGaussianNoise(np.zeros(1), np.full(1, 0.2), decay_steps=1000)
    model = ADC("MlpPolicy", "Pendulum-v1", action_noise=noise, policy_kwargs=TINY, **FAST)
    model.learn(100)
    model.save(tmp_path / "adc")
    loaded = ADC.load(tmp_path / "adc")
    assert loaded.action_noise.n_calls == 100


def test_vectorized_envs_and_vecnormalize():
    env = VecNormalize(make_vec_env("Pendulum-v1", n_envs=2, seed=0))
    model = ADC("MlpPolicy", env, policy_kwargs=TINY, **FAST)
    model.learn(200)
    assert model.n_envs == 2
    assert model.num_timesteps == 200
    assert model.replay_buffer.size() == 100  # 100 steps of each of the 2 envs
    mean_reward, _ = evaluate_policy(model, env, n_eval_episodes=2)
    assert np.isfinite(mean_reward)


def test_eval_and_checkpoint_callbacks(tmp_path):
    eval_env = gym.make("Pendulum-v1")
    eval_callback = EvalCallback(eval_env, eval_freq=100, n_eval_episodes=1, log_path=str(tmp_path), verbose=0)
    checkpoint = CheckpointCallback(save_freq=100, save_path=str(tmp_path / "ckpt"), save_replay_buffer=True)
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, **FAST)
    model.learn(200, callback=[eval_callback, checkpoint], progress_bar=True)
    evaluations = np.load(tmp_path / "evaluations.npz")
    assert evaluations["timesteps"].tolist() == [100, 200]
    saved = sorted(p.name for p in (tmp_path / "ckpt").iterdir())
    assert saved == [
        "rl_model_100_steps.zip",
        "rl_model_200_steps.zip",
        "rl_model_replay_buffer_100_steps.pkl",
        "rl_model_replay_buffer_200_steps.pkl",
    ]
    resumed = ADC.load(tmp_path / "ckpt" / "rl_model_200_steps.zip", env=gym.make("Pendulum-v1"))
    resumed.load_replay_buffer(tmp_path / "ckpt" / "rl_model_replay_buffer_200_steps.pkl")
    assert resumed.num_timesteps == 200
    # SB3 runs the callbacks before it stores the step's transition: the buffer saved at step 200 holds 199.
    assert resumed.replay_buffer.size() == 199


def test_cnn_policy_on_images():
    env = FakeImageEnv(screen_height=36, screen_width=36, discrete=False)
    model = ADC("CnnPolicy", env, policy_kwargs=dict(n_intervals=4, net_arch=[8]), **dict(FAST, buffer_size=200))
    assert isinstance(model.policy, CnnPolicy)
    model.learn(80)
    action, _ = model.predict(env.observation_space.sample(), deterministic=True)
    assert action.shape == env.action_space.shape


def test_multi_input_policy_on_dict_observations():
    env = SimpleMultiObsEnv(discrete_actions=False)
    model = ADC("MultiInputPolicy", env, policy_kwargs=dict(n_intervals=4, net_arch=[8]), **dict(FAST, buffer_size=200))
    assert isinstance(model.policy, MultiInputPolicy)
    model.learn(80)
    action, _ = model.predict(env.observation_space.sample(), deterministic=True)
    assert action.shape == (4,)


def test_predictions_stay_inside_the_action_bounds():
    model = ADC("MlpPolicy", "MountainCarContinuous-v0", policy_kwargs=TINY, **FAST)
    obs = observations(model.env.envs[0], n=50)
    actions, _ = model.predict(obs, deterministic=True)
    space = model.action_space
    assert np.all(actions >= space.low)
    assert np.all(actions <= space.high)


def test_drop_in_for_ddpg_with_the_same_arguments():
    arguments = dict(learning_rate=1e-3, tau=0.01, gamma=0.9, train_freq=1, gradient_steps=1, **FAST)
    ddpg = DDPG("MlpPolicy", "Pendulum-v1", policy_kwargs=dict(net_arch=[16]), **arguments)
    adc = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, **arguments)
    for model in (ddpg, adc):
        model.learn(80)
    # Same actor architecture; the critic adds the interval outputs on top of the shared trunk.
    assert [p.shape for p in ddpg.actor.parameters()] == [p.shape for p in adc.actor.parameters()]


def test_dummy_vec_env_with_one_env_and_predict_batch():
    env = DummyVecEnv([lambda: gym.make("Pendulum-v1")])
    model = ADC("MlpPolicy", env, policy_kwargs=TINY, **FAST)
    obs = env.reset()
    action, state = model.predict(obs, deterministic=True)
    assert action.shape == (1, 1)
    assert state is None


def learning_rates(model):
    return model.actor.optimizer.param_groups[0]["lr"], model.critic.optimizer.param_groups[0]["lr"]


@pytest.mark.parametrize("algorithm", ["adc", "split_rate_ddpg"])
def test_replacing_lr_schedule_on_a_live_model_moves_the_default_critic_rate(algorithm):
    # SB3's tests (and users fine-tuning a model) assign `model.lr_schedule`; with critic_learning_rate=None the
    # critic's rate is defined from the actor's at every point, so it must follow the new schedule.
    from sb3_adc.baselines import SplitRateDDPG

    if algorithm == "adc":
        model, factor = ADC("MlpPolicy", "Pendulum-v1", learning_rate=1e-3, policy_kwargs=TINY, **FAST), 2.0
    else:
        ddpg_kwargs = dict(policy_kwargs=dict(net_arch=[16]), **FAST)
        model, factor = SplitRateDDPG("MlpPolicy", "Pendulum-v1", learning_rate=1e-3, **ddpg_kwargs), 1.0
    model.learn(60)
    assert learning_rates(model) == pytest.approx((1e-3, factor * 1e-3))
    model.lr_schedule = lambda progress: 4e-4 * (1 + progress)
    model.learn(60, reset_num_timesteps=False)
    actor_lr, critic_lr = learning_rates(model)
    assert 4e-4 <= actor_lr < 8e-4
    assert critic_lr == pytest.approx(factor * actor_lr)
    # Frozen learning (SB3's test_cnn does this): neither network moves.
    model.lr_schedule = lambda _: 0.0
    critic_before = [p.detach().clone() for p in model.critic.parameters()]
    model.train(gradient_steps=1, batch_size=16)
    assert learning_rates(model) == (0.0, 0.0)
    for before, after in zip(critic_before, model.critic.parameters(), strict=True):
        assert th.equal(before, after)


def test_an_explicit_critic_rate_stays_when_lr_schedule_is_replaced():
    model = ADC("MlpPolicy", "Pendulum-v1", learning_rate=1e-3, critic_learning_rate=5e-3, policy_kwargs=TINY, **FAST)
    model.lr_schedule = lambda _: 1e-4
    model.learn(60)
    assert learning_rates(model) == pytest.approx((1e-4, 5e-3))
    # Assigning the critic's schedule sets `critic_learning_rate`, which is saved with the model.
    model.critic_lr_schedule = 7e-4
    model.learn(60, reset_num_timesteps=False)
    assert learning_rates(model) == pytest.approx((1e-4, 7e-4))
    assert model.critic_learning_rate == 7e-4


def test_load_with_the_policy_kwargs_of_construction(tmp_path):
    # SB3's tests (and users) pass the constructor's policy_kwargs again to `load`; SB3 refuses kwargs that differ
    # from the saved ones, which for ADC also record the critic design.
    model = ADC("MlpPolicy", "Pendulum-v1", policy_kwargs=TINY, **FAST)
    model.save(tmp_path / "adc.zip")
    loaded = ADC.load(tmp_path / "adc.zip", env=gym.make("Pendulum-v1"), policy_kwargs=TINY)
    assert loaded.policy.n_intervals == 8
    assert loaded.critic.critic_design == model.critic.critic_design
    with pytest.raises(ValueError, match="policy kwargs do not equal the stored policy kwargs"):
        ADC.load(tmp_path / "adc.zip", policy_kwargs=dict(TINY, n_intervals=9))
