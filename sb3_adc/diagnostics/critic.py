"""The critic diagnostics of a TD3-family model and the callback that logs them (see :mod:`sb3_adc.diagnostics`)."""

from __future__ import annotations

import math
import os
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.type_aliases import PyTorchObs
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, sync_envs_normalization

from sb3_adc.diagnostics.history import ADVANTAGE_PROFILE_KEY, ARRAY_KEYS, INTERVAL_VISITS_KEY, History, save_history

#: Keys of :func:`evaluate_critic`.
EVAL_KEYS = ("eval/critic_bias", "eval/critic_bias_abs", "eval/mc_return_mean", "eval/q_mean", "eval/mc_truncation_weight")
#: Keys of :func:`gradient_norms`.
GRADIENT_KEYS = ("train/actor_grad_norm", "train/dq_da_norm")
#: Scalar keys of the dueling interval critic (ADC only).
INTERVAL_KEYS: tuple[str, ...] = ("train/interval_visits_min_fraction", "train/interval_visits_unvisited")
INTERVAL_KEYS += ("train/advantage_roughness", "train/advantage_neighbour_diff")


def _check_td3_family(model: BaseAlgorithm) -> None:
    """Raise ``TypeError`` unless ``model`` has what the diagnostics read."""
    missing = [name for name in ("actor", "critic", "replay_buffer", "gamma") if not hasattr(model, name)]
    if missing or not hasattr(getattr(model, "critic", None), "q1_forward") or not isinstance(model.action_space, spaces.Box):
        raise TypeError(
            "the critic diagnostics need a TD3-family model (ADC, TD3, DDPG, SplitRateDDPG: an actor, a critic with "
            f"`q1_forward`, a replay buffer and a Box action space), got {type(model).__name__}"
        )


def is_interval_critic(model: BaseAlgorithm) -> bool:
    """
    Whether the model's critic is ADC's dueling interval critic (it has a ``partition``).

    :param model: A TD3-family model
    """
    return hasattr(model.critic, "partition")  # type: ignore[attr-defined]


def discounted_returns(rewards: np.ndarray, gamma: float) -> np.ndarray:
    """
    The discounted Monte-Carlo return ``G_t = sum_{k >= t} gamma^(k - t) r_k`` of every step of one episode.

    :param rewards: ``(T,)`` rewards of the episode, in order
    :param gamma: Discount factor
    :return: ``(T,)``
    """
    returns = np.zeros(len(rewards) + 1, dtype=np.float64)
    for step in range(len(rewards) - 1, -1, -1):
        returns[step] = float(rewards[step]) + gamma * returns[step + 1]
    return returns[:-1]


def truncation_weights(length: int, gamma: float, truncated: bool) -> np.ndarray:
    """
    The weight ``gamma^H`` of the return ``gamma^H V(s_T)`` missing from ``G_t`` of each step of an episode cut at
    truncation, ``H = T - t`` steps before the cut; zero for an episode that terminated.

    :param length: Number of steps ``T`` of the episode
    :param gamma: Discount factor
    :param truncated: Whether the episode was truncated (a time limit) rather than terminated
    :return: ``(T,)``
    """
    return gamma ** np.arange(length, 0, -1, dtype=np.float64) if truncated else np.zeros(length, dtype=np.float64)


def _stack_observations(observations: list[Any]) -> np.ndarray | dict[str, np.ndarray]:
    if isinstance(observations[0], dict):
        return {key: np.stack([obs[key] for obs in observations]) for key in observations[0]}
    return np.stack(observations)


def _check_positive_int(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"`{name}` must be an integer >= 1, got {value!r}")


def _check_evaluation_options(n_eval_episodes: object, tolerance: object) -> None:
    """Raise ``ValueError`` naming the option of :func:`evaluate_critic` that is invalid."""
    _check_positive_int("n_eval_episodes", n_eval_episodes)
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) or not 0 < tolerance <= 1:
        raise ValueError(f"`truncation_tolerance` must be a number in (0, 1], got {tolerance!r}")


def evaluate_critic(
    model: BaseAlgorithm, env: gym.Env | VecEnv, n_eval_episodes: int = 5, truncation_tolerance: float = 0.05
) -> dict[str, float]:
    """
    The critic's estimation bias ``Q(s_t, a_t) - G_t`` on deterministic rollouts of SB3's ``evaluate_policy``
    (the TD3 paper's over-estimation measure): ``Q`` from ``critic.q1_forward`` at the scaled action, ``G_t`` the
    discounted Monte-Carlo return of the rewards the environment returns, with the model's ``gamma``.

    A truncated episode's ``G_t`` misses ``gamma^H V(s_T)``, ``H`` steps before the cut (SB3 bootstraps through
    time limits), so only its steps with ``gamma^H <= truncation_tolerance`` count (at least its first step);
    every step of an episode that terminated counts. ``eval/mc_truncation_weight``, the mean ``gamma^H`` of the
    steps used, bounds the error: ``|G_t - true return| <= gamma^H max|V|``.

    :param model: A TD3-family model
    :param env: The evaluation environment (a separate instance from the training one)
    :param n_eval_episodes: Number of episodes
    :param truncation_tolerance: Largest ``gamma^H`` of a used step of a truncated episode, in ``(0, 1]``
    :return: The means over the steps used of :data:`EVAL_KEYS`: ``Q - G``, ``|Q - G|``, ``G``, ``Q``, ``gamma^H``
    """
    _check_evaluation_options(n_eval_episodes, truncation_tolerance)
    _check_td3_family(model)
    if not isinstance(env, VecEnv):
        env = DummyVecEnv([lambda: env])  # type: ignore[list-item, return-value]
    gamma = float(model.gamma)  # type: ignore[attr-defined]
    current: list[list[tuple[Any, np.ndarray, float]]] = [[] for _ in range(env.num_envs)]
    episodes: list[tuple[list[tuple[Any, np.ndarray, float]], bool]] = []

    def record_step(local_vars: dict[str, Any], _globals: dict[str, Any]) -> None:
        # evaluate_policy calls this for each env ``i`` after each step, before it moves on to the next observation.
        index, observations = local_vars["i"], local_vars["observations"]
        is_dict = isinstance(observations, dict)
        obs = {key: value[index] for key, value in observations.items()} if is_dict else observations[index]
        current[index].append((obs, np.asarray(local_vars["actions"][index]), float(local_vars["reward"])))
        if local_vars["done"]:
            episodes.append((current[index], bool(local_vars["info"].get("TimeLimit.truncated", False))))
            current[index] = []

    evaluate_policy(model, env, n_eval_episodes, deterministic=True, callback=record_step, warn=False)
    used_steps = []  # per episode: Q, G and gamma^H of the steps used
    for steps, truncated in episodes:
        observations = _stack_observations([obs for obs, _, _ in steps])
        actions = model.policy.scale_action(np.stack([action for _, action, _ in steps]))
        obs_tensor, _ = model.policy.obs_to_tensor(observations)
        with th.no_grad():
            q = model.critic.q1_forward(obs_tensor, th.as_tensor(actions, device=model.device, dtype=th.float32))  # type: ignore[attr-defined]
        returns = discounted_returns(np.array([reward for _, _, reward in steps]), gamma)
        weight = truncation_weights(len(steps), gamma, truncated)
        used = weight <= truncation_tolerance
        used[0] |= not used.any()  # at least the first step
        used_steps.append((q.cpu().numpy().reshape(-1)[used], returns[used], weight[used]))
    q_all, g_all, weights = (np.concatenate(values).astype(np.float64) for values in zip(*used_steps, strict=True))
    bias = q_all - g_all
    means = (bias, np.abs(bias), g_all, q_all, weights)
    return {key: float(values.mean()) for key, values in zip(EVAL_KEYS, means, strict=True)}


def gradient_norms(model: BaseAlgorithm, observations: PyTorchObs) -> dict[str, float]:
    """
    How strongly the critic pushes the actor on a batch of observations (no optimizer step, no ``.grad`` left).

    :param model: A TD3-family model
    :param observations: A batch of observations (as the replay buffer samples them)
    :return: ``train/actor_grad_norm``, the L2 norm of the gradient of TD3's actor loss over the actor's parameters,
        and ``train/dq_da_norm``, the batch mean of ``|dQ/da|`` at ``a = mu(s)`` (scaled actions)
    """
    _check_td3_family(model)
    actor, critic = model.actor, model.critic  # type: ignore[attr-defined]
    parameters = [parameter for parameter in actor.parameters() if parameter.requires_grad]
    with th.enable_grad():
        # autograd.grad returns the gradients instead of accumulating them into ``.grad``.
        actor_loss = -critic.q1_forward(observations, actor(observations)).mean()
        actor_grads = th.autograd.grad(actor_loss, parameters, allow_unused=True)
        actions = actor(observations).detach().requires_grad_(True)
        (dq_da,) = th.autograd.grad(critic.q1_forward(observations, actions).sum(), [actions])
    squared = sum(float(grad.pow(2).sum()) for grad in actor_grads if grad is not None)
    return {"train/actor_grad_norm": math.sqrt(squared), "train/dq_da_norm": float(dq_da.norm(dim=1).mean())}


def interval_visits(model: BaseAlgorithm) -> np.ndarray:
    """
    ADC only: how many of the actions stored in the replay buffer fall in each interval of the critic's partition.

    :param model: An ADC model
    :return: ``int64`` counts ``(action_dim, n_intervals)``
    """
    if not is_interval_critic(model):
        raise TypeError(f"interval visits need ADC's dueling interval critic, got {type(model).__name__}")
    partition = model.critic.partition  # type: ignore[attr-defined]
    buffer = model.replay_buffer  # type: ignore[attr-defined]
    n_intervals = partition.n_intervals
    stored = buffer.actions[: buffer.size()].reshape(-1, buffer.action_dim)
    index = partition.index(th.as_tensor(stored, dtype=th.float32, device=partition.edges.device))
    # One bincount for every dimension: dimension d's intervals are the bins [d * n, (d + 1) * n).
    offsets = th.arange(buffer.action_dim, device=index.device) * n_intervals
    counts = th.bincount((index + offsets).reshape(-1), minlength=buffer.action_dim * n_intervals)
    return counts.view(buffer.action_dim, n_intervals).cpu().numpy().astype(np.int64)


def advantage_roughness(advantages: th.Tensor) -> dict[str, float]:
    """
    How smooth an advantage is across neighbouring intervals.

    :param advantages: ``(batch, branches, n_intervals)``, from :meth:`~sb3_adc.DuelingIntervalCritic.decompose`
    :return: ``train/advantage_neighbour_diff``, the mean ``|A(z + 1) - A(z)|``, and ``train/advantage_roughness``,
        that over the advantage's mean standard deviation across intervals: 0 for a constant advantage, about
        ``3.5 / n`` for one linear over ``n`` intervals, about 1.13 for independent noise
    """
    diff = float((advantages[..., 1:] - advantages[..., :-1]).abs().mean())
    spread = float(advantages.std(dim=-1, correction=0).mean())
    return {"train/advantage_neighbour_diff": diff, "train/advantage_roughness": diff / spread if spread > 0 else 0.0}


def batch_diagnostics(model: BaseAlgorithm, batch_size: int | None = None) -> dict[str, Any]:
    """
    The diagnostics of one replay batch: :func:`gradient_norms` and, for ADC, interval visits and advantage profile.

    :param model: A TD3-family model with a non-empty replay buffer
    :param batch_size: Size of the batch; ``None``: the model's ``batch_size``
    :return: :data:`GRADIENT_KEYS`, and for ADC :data:`INTERVAL_KEYS`, :data:`INTERVAL_VISITS_KEY` and
        :data:`ADVANTAGE_PROFILE_KEY` (the centred advantage averaged over the batch, ``(branches, n_intervals)``)
    """
    _check_td3_family(model)
    buffer = model.replay_buffer  # type: ignore[attr-defined]
    if buffer.size() == 0:
        raise ValueError("the replay buffer is empty: the batch diagnostics need stored transitions")
    batch = buffer.sample(batch_size or model.batch_size, env=model.get_vec_normalize_env())  # type: ignore[attr-defined]
    results: dict[str, Any] = gradient_norms(model, batch.observations)
    if is_interval_critic(model):
        counts = interval_visits(model)
        results["train/interval_visits_min_fraction"] = float(counts.min() / counts[0].sum())
        results["train/interval_visits_unvisited"] = int((counts == 0).sum())
        results[INTERVAL_VISITS_KEY] = counts
        with th.no_grad():
            _, advantages, _ = model.critic.decompose(batch.observations, batch.actions)  # type: ignore[attr-defined]
        results.update(advantage_roughness(advantages))
        centred = advantages - advantages.mean(dim=-1, keepdim=True)
        results[ADVANTAGE_PROFILE_KEY] = centred.mean(dim=0).cpu().numpy().astype(np.float64)
    return results


class CriticDiagnosticsCallback(BaseCallback):
    """
    Log the critic diagnostics of a TD3-family model (ADC, TD3, DDPG, SplitRateDDPG) during training:
    :func:`evaluate_critic` every ``eval_freq`` calls, :func:`batch_diagnostics` every ``log_freq`` calls (calls
    count steps of the vectorised training environment, as with SB3's ``EvalCallback``). The values go to the
    logger and to :attr:`history`, one record per log time, written to ``save_path`` after each record.

    :param eval_env: The evaluation environment, a ``VecEnv`` or a Gymnasium id (not the training environment)
    :param eval_freq: Evaluate the critic every ``eval_freq`` calls, an integer >= 1
    :param n_eval_episodes: Evaluation episodes per evaluation, an integer >= 1
    :param log_freq: Compute the batch diagnostics every ``log_freq`` calls, an integer >= 1
    :param batch_size: Size of the replay batch (an integer >= 1); ``None``: the model's ``batch_size``
    :param truncation_tolerance: See :func:`evaluate_critic`, in ``(0, 1]``
    :param save_path: Folder of the history, ``{seed}`` standing for the model's seed; ``None``: in memory only
    :param verbose: 1 to print the bias after each evaluation
    """

    def __init__(
        self,
        eval_env: gym.Env | VecEnv | str,
        eval_freq: int = 10_000,
        n_eval_episodes: int = 5,
        log_freq: int = 1_000,
        batch_size: int | None = None,
        truncation_tolerance: float = 0.05,
        save_path: str | None = None,
        verbose: int = 0,
    ):
        super().__init__(verbose)
        _check_positive_int("eval_freq", eval_freq)
        _check_positive_int("log_freq", log_freq)
        if batch_size is not None:
            _check_positive_int("batch_size", batch_size)
        _check_evaluation_options(n_eval_episodes, truncation_tolerance)  # fail before training
        if isinstance(eval_env, str):
            eval_env = make_vec_env(eval_env, n_envs=1)
        elif not isinstance(eval_env, VecEnv):
            eval_env = DummyVecEnv([lambda: eval_env])  # type: ignore[list-item, return-value]
        self.eval_env: VecEnv = eval_env
        self.eval_freq, self.log_freq, self.batch_size = eval_freq, log_freq, batch_size
        self.n_eval_episodes, self.truncation_tolerance = n_eval_episodes, float(truncation_tolerance)
        self.save_path = save_path
        self.history: History = []

    def _init_callback(self) -> None:
        _check_td3_family(self.model)
        if self.save_path is not None:
            self.save_path = self.save_path.replace("{seed}", str(self.model.seed))
            os.makedirs(self.save_path, exist_ok=True)

    def _on_step(self) -> bool:
        record: dict[str, Any] = {}
        if self.n_calls % self.eval_freq == 0:
            # Evaluate with the training environment's normalisation statistics, as EvalCallback does (and only
            # then: other wrappers of the training environment, such as a NaN check, need no match here).
            if self.model.get_vec_normalize_env() is not None:
                sync_envs_normalization(self.training_env, self.eval_env)
            record.update(evaluate_critic(self.model, self.eval_env, self.n_eval_episodes, self.truncation_tolerance))
            if self.verbose >= 1:
                print(
                    f"Critic at {self.num_timesteps} steps: bias {record['eval/critic_bias']:+.2f} "
                    f"(Q {record['eval/q_mean']:.2f}, Monte-Carlo return {record['eval/mc_return_mean']:.2f})"
                )
        if self.n_calls % self.log_freq == 0 and self.model.replay_buffer.size() > 0:  # type: ignore[attr-defined]
            record.update(batch_diagnostics(self.model, self.batch_size))
        if record:
            for key, value in record.items():
                if key not in ARRAY_KEYS:
                    self.logger.record(key, value)
            self.history.append({"timesteps": self.num_timesteps, **record})
            if self.save_path is not None:
                save_history(self.history, self.save_path)
        return True
