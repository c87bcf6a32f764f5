"""ADC's fast update path (``fast_update=True``) learns what the plain path learns, up to float rounding."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th

from sb3_adc import ADC
from sb3_adc.adc.options import check_fast_update

#: The ``-v1`` lidar entries' update settings (hyperparams/adc.yml), scaled down: twin critics, 3-step returns,
#: policy delay, target smoothing and an averaged actor.
SETTINGS: dict[str, Any] = dict(
    gamma=0.98,
    batch_size=32,
    learning_rate=1e-3,
    critic_learning_rate=1e-3,
    tau=0.01,
    learning_starts=10_000,
    n_steps=3,
    policy_delay=2,
    target_policy_noise=0.2,
    target_noise_clip=0.5,
    device="cpu",
    seed=3,
)
NETWORKS: dict[str, Any] = dict(
    net_arch=dict(pi=[32, 16], qf=[32]), value_net_arch=[8], advantage_net_arch=[8], n_critics=2, actor_average_tau=1e-2
)


def _model(fast_update: bool, **policy_kwargs: Any) -> ADC:
    return ADC("MlpPolicy", "Pendulum-v1", fast_update=fast_update, policy_kwargs={**NETWORKS, **policy_kwargs}, **SETTINGS)


def _parameters(model: ADC) -> dict[str, th.Tensor]:
    """Every parameter of the policy (actor, critic, their targets and the averaged actor), by name."""
    return {name: tensor.detach().clone() for name, tensor in model.policy.state_dict().items()}


@pytest.mark.parametrize(
    "policy_kwargs",
    [
        pytest.param({}, id="legendre-default"),
        pytest.param(dict(critic_design="paper", n_intervals=20), id="paper"),
        pytest.param(
            dict(net_arch=dict(pi=[32], qf=[32]), value_net_arch=[], advantage_net_arch=[]), id="legendre-fused-heads"
        ),
    ],
)
def test_fast_update_learns_what_the_plain_update_learns(policy_kwargs: dict[str, Any]) -> None:
    fast = _model(True, **policy_kwargs)
    fast.learn(300)  # fills the replay buffer (learning_starts is higher: no update yet)
    plain = _model(False, **policy_kwargs)
    plain.learn(1)  # sets up its logger
    plain.policy.load_state_dict(fast.policy.state_dict())
    plain.replay_buffer = copy.deepcopy(fast.replay_buffer)
    before = _parameters(fast)
    assert th.equal(th.cat([p.flatten() for p in before.values()]), th.cat([p.flatten() for p in _parameters(plain).values()]))

    for model in (fast, plain):
        # The same batches and the same target-smoothing noise for both.
        np.random.seed(0)
        th.manual_seed(0)
        model.train(gradient_steps=2, batch_size=32)

    after_fast, after_plain = _parameters(fast), _parameters(plain)
    assert after_fast.keys() == after_plain.keys() == before.keys()
    moved = [name for name in before if not th.equal(before[name], after_plain[name])]
    # The critic, the actor (one update: policy_delay=2), both targets and the averaged actor moved.
    for prefix in ("critic.", "critic_target.", "actor.", "actor_target.", "actor_average."):
        assert any(name.startswith(prefix) for name in moved), prefix
    for name in before:
        th.testing.assert_close(after_fast[name], after_plain[name], rtol=1e-5, atol=1e-7, msg=name)


def test_fast_update_batches_the_twin_critics_of_the_default_design() -> None:
    model = _model(True)
    model.learn(200)
    model.train(gradient_steps=1, batch_size=16)
    assert model._stacked_critics is not None
    observations = th.randn(16, 3)
    actions = th.rand(16, 1) * 2 - 1
    with th.no_grad():
        for target, critic in ((False, model.critic), (True, model.critic_target)):
            one_by_one = th.stack(critic(observations, actions))
            th.testing.assert_close(model._q_values(target, observations, actions), one_by_one, rtol=1e-5, atol=1e-6)
    # The paper's design keeps the per-critic path.
    paper = _model(True, critic_design="paper", n_intervals=20)
    paper.learn(200)
    paper.train(gradient_steps=1, batch_size=16)
    assert paper._stacked_critics is None


def test_fast_update_saves_and_loads_the_plain_parameters(tmp_path: Path) -> None:
    model = _model(True)
    model.learn(200)
    model.train(gradient_steps=2, batch_size=16)
    plain_keys = _model(False).policy.state_dict().keys()
    assert model.policy.state_dict().keys() == plain_keys
    model.save(tmp_path / "fast.zip")
    loaded = ADC.load(tmp_path / "fast.zip", env=gym.make("Pendulum-v1"), device="cpu")
    assert loaded.fast_update
    for name, tensor in _parameters(model).items():
        assert th.equal(tensor, loaded.policy.state_dict()[name]), name
    # A plain model loads the fast model's file, and the loaded model trains on its parameters.
    plain = ADC.load(tmp_path / "fast.zip", env=gym.make("Pendulum-v1"), device="cpu", fast_update=False)
    assert not plain.fast_update
    loaded.learn(1)  # sets up its logger
    loaded.replay_buffer = copy.deepcopy(model.replay_buffer)
    loaded.train(gradient_steps=1, batch_size=16)
    observations, actions = th.randn(8, 3), th.rand(8, 1) * 2 - 1
    with th.no_grad():
        th.testing.assert_close(
            loaded._q_values(False, observations, actions),
            th.stack(loaded.critic(observations, actions)),
            rtol=1e-5,
            atol=1e-6,
        )


def test_fused_adam_is_a_default_that_an_explicit_choice_overrides() -> None:
    model = _model(True)
    assert model.actor.optimizer.param_groups[0]["fused"] is True
    assert model.critic.optimizer.param_groups[0]["fused"] is True
    chosen = ADC(
        "MlpPolicy",
        "Pendulum-v1",
        policy_kwargs=dict(optimizer_kwargs=dict(foreach=True)),
        device="cpu",
        learning_starts=10,
        fast_update=True,
    )
    chosen.learn(20)
    for optimizer in (chosen.actor.optimizer, chosen.critic.optimizer):
        assert optimizer.param_groups[0]["foreach"] is True
        assert not optimizer.param_groups[0]["fused"]
    plain = _model(False)
    plain.learn(200)
    plain.train(gradient_steps=1, batch_size=16)
    assert not plain.critic.optimizer.param_groups[0]["fused"]


@pytest.mark.parametrize("value", [1, "yes", None])
def test_fast_update_must_be_a_bool(value: object) -> None:
    with pytest.raises(ValueError, match="fast_update"):
        check_fast_update(value)
    with pytest.raises(ValueError, match="fast_update"):
        ADC("MlpPolicy", "Pendulum-v1", fast_update=value)  # type: ignore[arg-type]


def test_hyperparameter_files_accept_fast_update() -> None:
    from sb3_adc.config import resolve_entry
    from sb3_adc.config.errors import HyperparamsError

    def entry(value: object) -> Any:
        return resolve_entry("adc", "Pendulum-v1", {"n_timesteps": 10, "policy": "MlpPolicy", "fast_update": value}, "test")

    assert entry(False).model_kwargs["fast_update"] is False
    with pytest.raises(HyperparamsError, match="fast_update"):
        entry("no")


def test_the_batched_critics_follow_parameters_given_new_storage() -> None:
    model = _model(True)
    model.learn(200)
    model.train(gradient_steps=1, batch_size=16)
    # As `.to(another_device)` or a deepcopy would: every parameter gets storage of its own.
    with th.no_grad():
        for critic in (model.critic, model.critic_target):
            for parameter in critic.parameters():
                parameter.data = parameter.data.clone() + 0.01
    observations, actions = th.randn(8, 3), th.rand(8, 1) * 2 - 1
    with th.no_grad():
        expected = th.stack(model.critic(observations, actions))
        # Between `train` calls, the critics' own values (the stale stacks are not used).
        th.testing.assert_close(model._q_values(False, observations, actions), expected, rtol=0, atol=0)
    model.train(gradient_steps=1, batch_size=16)
    assert model._stacked_critics is not None
    assert all(stacked.is_linked() for stacked in model._stacked_critics)
    with th.no_grad():
        for target, critic in ((False, model.critic), (True, model.critic_target)):
            th.testing.assert_close(
                model._q_values(target, observations, actions), th.stack(critic(observations, actions)), rtol=1e-5, atol=1e-6
            )
