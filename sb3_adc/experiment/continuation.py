"""
Exact resume: what a checkpoint holds beyond SB3's model and replay buffer, so that a resumed run is the run it
continues, draw for draw. A :class:`Continuation` (``rl_model_continuation_{t}_steps.pkl``) keeps the random
generators, each environment's episode in progress (its generators before the reset and the actions since, replayed
by :class:`EpisodeRecorder`) and the step a periodic checkpoint is taken inside (:class:`PendingStep`).

Not exact (resumed on a new random stream): checkpoints of a Ctrl-C that fell anywhere, of older versions, of runs
with ``frame_stack`` or other stateful ``VecEnv`` wrappers or gSDE, and of rollouts a checkpoint cuts.
"""

from __future__ import annotations

import copy
import random
from dataclasses import dataclass, field
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.utils import should_collect_more_steps
from stable_baselines3.common.vec_env import VecCheckNan, VecEnv, VecEnvWrapper, VecNormalize, unwrap_vec_normalize

#: Version of the continuation format (a file of another version is not used).
CONTINUATION_VERSION = 1

#: ``VecEnv`` wrappers whose state a continuation restores (``VecCheckNan`` keeps none that matters).
_RESTORABLE_VEC_WRAPPERS = (VecCheckNan, VecNormalize)


def generator_states(env: gym.Env[Any, Any]) -> dict[tuple[int, str], Any]:
    """
    The states of the random generators of every layer of an environment (``np_random``, a wrapper's own).

    :param env: The environment (wrapped or not)
    :return: ``(depth, attribute) -> state``, depth 0 being ``env`` itself
    """
    states: dict[tuple[int, str], Any] = {}
    for depth, layer in enumerate(_layers(env)):
        for name, value in vars(layer).items():
            if isinstance(value, np.random.Generator):
                states[(depth, name)] = copy.deepcopy(value.bit_generator.state)
            elif isinstance(value, np.random.RandomState):
                states[(depth, name)] = value.get_state()
    return states


def set_generator_states(env: gym.Env[Any, Any], states: dict[tuple[int, str], Any]) -> None:
    """
    Restore the states of :func:`generator_states` into an environment built the same way (making a missing generator).

    :param env: The environment
    :param states: What :func:`generator_states` returned for the environment to continue
    """
    layers = _layers(env)
    for (depth, name), state in states.items():
        generator = vars(layers[depth]).get(name)
        if isinstance(state, dict):  # a Generator's
            if not isinstance(generator, np.random.Generator):
                generator = np.random.Generator(getattr(np.random, state["bit_generator"])())
                setattr(layers[depth], name, generator)
            generator.bit_generator.state = state
        else:
            if not isinstance(generator, np.random.RandomState):
                generator = np.random.RandomState()
                setattr(layers[depth], name, generator)
            generator.set_state(state)


def _layers(env: gym.Env[Any, Any]) -> list[gym.Env[Any, Any]]:
    layers = [env]
    while isinstance(layers[-1], gym.Wrapper):
        layers.append(layers[-1].env)
    return layers


@dataclass
class EpisodeRecord:
    """
    What replays an environment's episode in progress.

    :param generators: The states of its random generators before the episode's reset (:func:`generator_states`)
    :param seed: The reset's seed
    :param options: The reset's options
    :param actions: The actions taken since
    """

    generators: dict[tuple[int, str], Any]
    seed: int | None
    options: dict[str, Any] | None
    actions: list[Any] = field(default_factory=list)


class EpisodeRecorder(gym.Wrapper[Any, Any, Any, Any]):
    """
    Record the episode in progress (:class:`EpisodeRecord`) and replay one; outermost, so a replay goes through all.

    :param env: The environment
    """

    def __init__(self, env: gym.Env[Any, Any]):
        super().__init__(env)
        self._record: EpisodeRecord | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        self._record = EpisodeRecord(generator_states(self.env), seed, copy.deepcopy(options))
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        if self._record is not None:
            self._record.actions.append(action.copy() if isinstance(action, np.ndarray) else copy.deepcopy(action))
        return self.env.step(action)

    def episode_record(self) -> EpisodeRecord | None:
        """The record of the episode in progress (``None`` before the first reset)."""
        return copy.deepcopy(self._record)

    def replay_episode(self, record: EpisodeRecord) -> None:
        """
        Bring this environment, built as the recorded one was, to the recorded one's state: generators, reset, actions.

        :param record: What :meth:`episode_record` returned for the environment to continue
        """
        set_generator_states(self.env, record.generators)
        self.env.reset(seed=record.seed, options=copy.deepcopy(record.options))
        for action in record.actions:
            self.env.step(copy.deepcopy(action))
        self._record = copy.deepcopy(record)


@dataclass
class PendingStep:
    """
    The step a periodic checkpoint was taken inside: stepped, not yet stored nor trained on (``collect_rollouts``' locals).

    :param buffer_actions: The actions as stored in the replay buffer
    :param new_obs: The observations the step returned
    :param rewards: Its rewards
    :param dones: Its episode ends
    :param infos: Its infos
    :param num_collected_steps: Steps of the rollout so far, this one included
    :param num_collected_episodes: Episodes of the rollout that ended before this step
    :param original_obs: ``VecNormalize``'s unnormalized observations of the step (``None`` without it)
    :param original_reward: ``VecNormalize``'s unnormalized rewards of the step
    """

    buffer_actions: np.ndarray
    new_obs: Any
    rewards: np.ndarray
    dones: np.ndarray
    infos: list[dict[str, Any]]
    num_collected_steps: int
    num_collected_episodes: int
    original_obs: Any = None
    original_reward: np.ndarray | None = None

    @classmethod
    def of_locals(cls, variables: dict[str, Any], vec_normalize: VecNormalize | None) -> PendingStep | None:
        """
        The pending step of ``collect_rollouts``' locals, or ``None`` if the rollout goes on after it (not exact).

        :param variables: The locals SB3 gave the callbacks
        :param vec_normalize: The training environments' ``VecNormalize``, if any
        """
        dones = np.asarray(variables["dones"])
        episodes, steps = int(variables["num_collected_episodes"]), int(variables["num_collected_steps"])
        if should_collect_more_steps(variables["train_freq"], steps, episodes + int(dones.sum())):
            return None
        step = {name: copy.deepcopy(variables[name]) for name in ("buffer_actions", "new_obs", "rewards", "infos")}
        return cls(
            **step,
            dones=dones.copy(),
            num_collected_steps=steps,
            num_collected_episodes=episodes,
            original_obs=vec_normalize.get_original_obs() if vec_normalize is not None else None,
            original_reward=vec_normalize.get_original_reward() if vec_normalize is not None else None,
        )


@dataclass
class Continuation:
    """
    What a resumed run needs, beyond the model and the replay buffer, to be the run it continues.

    :param timesteps: The checkpoint's timestep
    :param random_states: Python's, NumPy's global and PyTorch's generators, and the model's action space's
    :param last_obs: The model's ``_last_obs`` (before the pending step, if any)
    :param last_original_obs: The model's ``_last_original_obs``
    :param last_episode_starts: The model's ``_last_episode_starts``
    :param training_episodes: The episode in progress of each training environment
    :param evaluation_episodes: The same for the evaluation environments (``None``: none)
    :param vec_normalize: ``VecNormalize``'s running discounted returns (``None`` without it)
    :param pending: The step the checkpoint was taken inside (``None``: taken between steps)
    :param version: :data:`CONTINUATION_VERSION`
    """

    timesteps: int
    random_states: dict[str, Any]
    last_obs: Any
    last_original_obs: Any
    last_episode_starts: Any
    training_episodes: list[EpisodeRecord | None]
    evaluation_episodes: list[EpisodeRecord | None] | None
    vec_normalize: dict[str, Any] | None
    pending: PendingStep | None
    version: int = CONTINUATION_VERSION

    @classmethod
    def capture(cls, model: BaseAlgorithm, eval_env: VecEnv | None, step_locals: dict[str, Any] | None) -> Continuation | None:
        """
        The continuation of a model now, or ``None`` where none is exact (see the module's docstring).

        :param model: The model being trained (its environment is the training one)
        :param eval_env: The evaluation environments of the run, if any
        :param step_locals: ``collect_rollouts``' locals when called inside a step, ``None`` between steps
        """
        env = model.get_env()
        if not isinstance(model, OffPolicyAlgorithm) or env is None or model.use_sde:
            return None
        if not _restorable(env) or (eval_env is not None and not _restorable(eval_env)):
            return None
        vec_normalize = unwrap_vec_normalize(env)
        pending = PendingStep.of_locals(step_locals, vec_normalize) if step_locals is not None else None
        if step_locals is not None and pending is None:
            return None
        random_states: dict[str, Any] = {
            "python": random.getstate(),
            "numpy": np.random.get_state(),  # noqa: NPY002 - SB3's replay buffers and action noises draw from it
            "torch": th.get_rng_state(),
            "action_space": copy.deepcopy(model.action_space.np_random.bit_generator.state),
        }
        if model.device.type == "cuda":
            random_states["cuda"] = th.cuda.get_rng_state(model.device)
        return cls(
            timesteps=model.num_timesteps,
            random_states=random_states,
            last_obs=copy.deepcopy(model._last_obs),  # SB3's state of the loop, which no API saves
            last_original_obs=copy.deepcopy(model._last_original_obs),
            last_episode_starts=copy.deepcopy(model._last_episode_starts),
            training_episodes=list(env.env_method("episode_record")),
            evaluation_episodes=list(eval_env.env_method("episode_record")) if eval_env is not None else None,
            vec_normalize={"returns": vec_normalize.returns.copy()} if vec_normalize is not None else None,
            pending=pending,
        )

    def restore(self, model: OffPolicyAlgorithm, eval_env: VecEnv | None, remaining: int) -> None:
        """
        Continue the run in ``model``: replay the episodes in progress, restore the loop's state and the generators,
        then store and train on the pending step.

        :param model: The model loaded from the checkpoint
        :param eval_env: The run's evaluation environments (``None``: none)
        :param remaining: The timesteps ``model.learn`` will be asked for
        """
        env = model.get_env()
        assert env is not None, "the model is loaded with its training environments"
        _replay(env, self.training_episodes)
        if eval_env is not None and self.evaluation_episodes is not None:
            _replay(eval_env, self.evaluation_episodes)
        vec_normalize = unwrap_vec_normalize(env)
        if vec_normalize is not None and self.vec_normalize is not None:
            vec_normalize.returns = self.vec_normalize["returns"].copy()
        model._last_obs = copy.deepcopy(self.last_obs)
        model._last_original_obs = copy.deepcopy(self.last_original_obs)
        model._last_episode_starts = copy.deepcopy(self.last_episode_starts)
        random.setstate(self.random_states["python"])
        np.random.set_state(self.random_states["numpy"])  # noqa: NPY002
        th.set_rng_state(self.random_states["torch"])
        model.action_space.np_random.bit_generator.state = self.random_states["action_space"]
        if "cuda" in self.random_states and model.device.type == "cuda":
            th.cuda.set_rng_state(self.random_states["cuda"], model.device)
        if self.pending is not None:
            _complete(model, self.pending, vec_normalize, remaining)


def _restorable(venv: VecEnv) -> bool:
    """Whether each environment has an :class:`EpisodeRecorder` and no ``VecEnv`` wrapper keeps a state of its own."""
    while isinstance(venv, VecEnvWrapper):
        if not isinstance(venv, _RESTORABLE_VEC_WRAPPERS):
            return False
        venv = venv.venv
    return venv.has_attr("replay_episode")


def _replay(venv: VecEnv, records: list[EpisodeRecord | None]) -> None:
    indices = [index for index, record in enumerate(records) if record is not None]
    for index in indices:
        venv.env_method("replay_episode", records[index], indices=[index])
    if indices:
        # The original run's first reset used the seeds: a later ``VecEnv.reset`` must not apply them again.
        venv.unwrapped._reset_seeds()
        venv.unwrapped._reset_options()


def _complete(model: OffPolicyAlgorithm, pending: PendingStep, vec_normalize: VecNormalize | None, remaining: int) -> None:
    """SB3 2.x's ``collect_rollouts`` after the step's callbacks, then ``learn``'s training (SB3 has no entry there)."""
    env, replay_buffer = model.get_env(), model.replay_buffer
    assert env is not None, "the model is loaded with its environments"
    assert replay_buffer is not None, "the model is loaded with its replay buffer"
    # What `learn` sets up before its loop (episode buffers, the vectorized noise, the timestep target).
    model._setup_learn(remaining, callback=None, reset_num_timesteps=False)
    if vec_normalize is not None:
        assert pending.original_reward is not None
        vec_normalize.old_obs = copy.deepcopy(pending.original_obs)
        vec_normalize.old_reward = pending.original_reward.copy()
    model._update_info_buffer(pending.infos, pending.dones)
    model._store_transition(
        replay_buffer, pending.buffer_actions, pending.new_obs, pending.rewards, pending.dones, pending.infos
    )
    model._update_current_progress_remaining(model.num_timesteps, model._total_timesteps)
    model._on_step()
    for index, done in enumerate(pending.dones):
        if done:
            model._episode_num += 1
            if model.action_noise is not None:
                model.action_noise.reset(**({"indices": [index]} if env.num_envs > 1 else {}))
    if model.num_timesteps > 0 and model.num_timesteps > model.learning_starts:
        gradient_steps = model.gradient_steps if model.gradient_steps >= 0 else pending.num_collected_steps * env.num_envs
        if gradient_steps > 0:
            model.train(batch_size=model.batch_size, gradient_steps=gradient_steps)
