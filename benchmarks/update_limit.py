"""
The tight-loop limit of ``training_throughput.py --fast-update``: the same environment, batch and update settings as
its models and the networks of its TD3, in a plain PyTorch loop without SB3 (issue 61's "the arithmetic itself").

Per environment step: the actor's action with Gaussian noise, one transition written to a preallocated buffer, and
one gradient step: 3-step targets gathered from the buffer with tensor indexing, the twin critics evaluated as one
batched module (``torch.baddbmm``), fused Adam steps, and every second step the actor's step and one Polyak update
over all target tensors (``torch._foreach_lerp_``). No logger, no callbacks, no host syncs in the update. What SB3
adds on top (rollout bookkeeping, replay-buffer classes, per-module calls) is the gap between this and the models.
"""

from __future__ import annotations

import copy
import itertools

import gymnasium as gym
import numpy as np
import torch as th
from torch import nn

#: Transitions the buffer holds (``COMMON["buffer_size"]`` of training_throughput.py).
BUFFER_SIZE = 100_000


class TwinMLP(nn.Module):
    """
    ``count`` MLPs of the same shape evaluated at once: the first layer, which reads the same input, one ``linear``
    over the concatenated weights, the others one batched matrix product each (as ``sb3_adc.adc.stacked``).
    """

    def __init__(self, sizes: list[int], count: int = 2) -> None:
        super().__init__()
        self.count, self.first = count, nn.Linear(sizes[0], count * sizes[1])
        self.weights = nn.ParameterList(
            nn.Parameter(th.randn(count, a, b) / np.sqrt(a)) for a, b in itertools.pairwise(sizes[1:])
        )
        self.biases = nn.ParameterList(nn.Parameter(th.zeros(count, 1, b)) for b in sizes[2:])

    def forward(self, x: th.Tensor, count: int | None = None) -> th.Tensor:
        """``x``: ``(batch, in)`` -> ``(count, batch, out)``, of the first ``count`` MLPs (``None``: all)."""
        x = self.first(x).view(x.shape[0], self.count, -1).transpose(0, 1)[:count]
        for weight, bias in zip(self.weights, self.biases, strict=True):
            x = th.baddbmm(bias[:count], th.relu(x), weight[:count])
        return x


class TightLoop:
    """
    The update of the ``-v1`` entries (twin critics, policy delay 2, target smoothing 0.2 clipped at 0.5, 3-step
    returns, ``tau=0.01``, ``gamma=0.98``, Adam at 1e-3) on ``env_id``, with ``learn`` as SB3's, for the timer.

    :param env_id: Environment id
    :param actor_arch: Actor's hidden layers
    :param critic_arch: Each critic's hidden layers
    :param batch_size: Batch (and steps before the first update)
    :param seed: Seed
    """

    def __init__(self, env_id: str, actor_arch: list[int], critic_arch: list[int], batch_size: int, seed: int) -> None:
        th.manual_seed(seed)
        self.env, self.rng, self.batch_size, self.step = gym.make(env_id), np.random.default_rng(seed), batch_size, 0
        observations, actions = self.env.observation_space, self.env.action_space
        assert isinstance(observations, gym.spaces.Box)
        assert isinstance(actions, gym.spaces.Box)
        obs_dim, act_dim = observations.shape[0], actions.shape[0]
        self.scale = actions.high
        layers: list[nn.Module] = []
        for a, b in itertools.pairwise([obs_dim, *actor_arch]):
            layers += [nn.Linear(a, b), nn.ReLU()]
        self.actor = nn.Sequential(*layers, nn.Linear(actor_arch[-1], act_dim), nn.Tanh())
        self.critic = TwinMLP([obs_dim + act_dim, *critic_arch, 1])
        self.actor_target, self.critic_target = copy.deepcopy(self.actor), copy.deepcopy(self.critic)
        self.actor_optimizer = th.optim.Adam(self.actor.parameters(), lr=1e-3, fused=True)
        self.critic_optimizer = th.optim.Adam(self.critic.parameters(), lr=1e-3, fused=True)
        self.online: list[th.Tensor] = [*self.actor.parameters(), *self.critic.parameters()]
        self.target: list[th.Tensor] = [*self.actor_target.parameters(), *self.critic_target.parameters()]
        size = BUFFER_SIZE
        self.buffer = {key: th.zeros(size, dim) for key, dim in (("obs", obs_dim), ("action", act_dim), ("reward", 1))}
        self.buffer |= {"next_obs": th.zeros(size, obs_dim), "done": th.zeros(size, 1)}
        self.obs, _ = self.env.reset(seed=seed)

    def learn(self, total_timesteps: int, reset_num_timesteps: bool = True) -> TightLoop:
        """Run ``total_timesteps`` environment steps, one gradient step each past the first batch."""
        for _ in range(total_timesteps):
            with th.no_grad():
                action = self.actor(th.as_tensor(self.obs, dtype=th.float32)[None])[0].numpy()
            action = np.clip(action + self.rng.normal(0, 0.1, action.shape), -1, 1)
            next_obs, reward, terminated, truncated, _ = self.env.step(action * self.scale)
            row = self.step % BUFFER_SIZE
            for key, value in (("obs", self.obs), ("action", action), ("reward", reward), ("next_obs", next_obs)):
                self.buffer[key][row] = th.as_tensor(value, dtype=th.float32)
            self.buffer["done"][row] = float(terminated or truncated)
            self.obs = self.env.reset()[0] if terminated or truncated else next_obs
            self.step += 1
            if self.step >= self.batch_size:
                self.train()
        return self

    def train(self, n_steps: int = 3, gamma: float = 0.98) -> None:
        """One gradient step (the actor's and the targets' every second step) on a batch of 3-step transitions."""
        filled = min(self.step, BUFFER_SIZE)
        index = th.randint(0, max(filled - n_steps, 1), (self.batch_size,))
        offsets = index[:, None] + th.arange(n_steps)
        dones = self.buffer["done"][offsets, 0]
        alive = th.cumprod(1 - dones, dim=1)  # 1 while no episode ended before this step
        weights = th.cat([th.ones(self.batch_size, 1), alive[:, :-1]], dim=1) * gamma ** th.arange(n_steps)
        returns = (weights * self.buffer["reward"][offsets, 0]).sum(dim=1, keepdim=True)
        last = index + alive[:, :-1].sum(dim=1).long()  # the window's last transition: where its episode ended
        obs, action, next_obs = self.buffer["obs"][index], self.buffer["action"][index], self.buffer["next_obs"][last]
        not_done = 1 - self.buffer["done"][last]
        with th.no_grad():
            noise = (th.randn_like(action) * 0.2).clamp(-0.5, 0.5)
            next_action = (self.actor_target(next_obs) + noise).clamp(-1, 1)
            target_q = self.critic_target(th.cat([next_obs, next_action], dim=1)).min(dim=0).values
            target = returns + not_done * gamma**n_steps * target_q
        critic_loss = ((self.critic(th.cat([obs, action], dim=1)) - target) ** 2).mean() * 2
        self.critic_optimizer.zero_grad(set_to_none=True)
        critic_loss.backward()
        self.critic_optimizer.step()
        if self.step % 2 == 0:
            actor_loss = -self.critic(th.cat([obs, self.actor(obs)], dim=1), count=1).mean()  # the first critic's Q
            self.actor_optimizer.zero_grad(set_to_none=True)
            actor_loss.backward()
            self.actor_optimizer.step()
            with th.no_grad():
                th._foreach_lerp_(self.target, self.online, 0.01)
