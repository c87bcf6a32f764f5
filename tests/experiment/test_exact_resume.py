"""
Exact resume: a run resumed from a periodic checkpoint is the uninterrupted run, parameter for parameter, episode
for episode and evaluation for evaluation (sb3_adc.experiment.continuation).
"""

from __future__ import annotations

import glob
import os
import signal

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.save_util import load_from_pkl, load_from_zip_file

from sb3_adc.experiment import RunInterrupted, TrainSettings, resume, train
from sb3_adc.experiment.continuation import EpisodeRecorder
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.manifest import write_manifest

BASE = """\
default:
  n_timesteps: 600
  policy: MlpPolicy
  learning_starts: 50
  batch_size: 16
  buffer_size: 1000
  gamma: 0.9
  policy_kwargs: "dict(net_arch=[8])"
"""
#: The exploration noise of the deterministic actors.
NOISE = """\
  noise_type: normal
  noise_std: 0.1
"""
LIDAR = """\
  env_kwargs:
    max_episode_steps: 120
    start_position_jitter: 0.2
    start_heading_jitter_deg: 15.0
    {sensor}
  env_wrapper:
    - sb3_adc_envs.wrappers.ClearanceShaping: {{gamma: 0.98}}
"""
#: (algorithm, environment, lines added to the configuration): every source of state a resume must restore.
CASES = {
    # ADC's epsilon-gated noise draws from NumPy's global generator; Pendulum's own generator draws the starts.
    "adc-pendulum": ("adc", "Pendulum-v1", NOISE),
    # Two environments, each with an episode in progress; the observation noise has its own generator; the
    # layouts, the start jitter and the reward shaping's state.
    "td3-noisy-lidar-2-envs": (
        "td3",
        "sb3_adc/LidarObstacleCourseNoisy-v1",
        NOISE + "  n_envs: 2\n" + LIDAR.format(sensor="rays_per_reading: 4"),
    ),
    # The wheeled robot's pybullet dynamics.
    "adc-wheeled-lidar": ("adc", "sb3_adc/LidarObstacleCourse-v1", NOISE + LIDAR.format(sensor="robot: wheeled")),
    # SAC samples its actions and updates its entropy coefficient from PyTorch's generator.
    "sac-pendulum": ("sac", "Pendulum-v1", ""),
    # DQN's epsilon-greedy exploration draws from NumPy's generator and the action space's; its target update
    # counts calls.
    "dqn-cartpole": ("dqn", "CartPole-v1", "  exploration_fraction: 0.5\n  target_update_interval: 50\n"),
    # VecNormalize's running statistics and discounted returns (episodes of 150 steps: one is in progress at
    # the checkpoint, so the returns are not zero).
    "td3-normalized-pendulum": (
        "td3",
        "Pendulum-v1",
        NOISE + "  normalize: true\n  env_kwargs: {max_episode_steps: 150}\n",
    ),
}


@pytest.fixture(scope="session")
def case_settings(tiny_settings, tmp_path_factory):
    """
    ``make(folder, case, **changes)``: a run of a case of :data:`CASES` logging under ``folder/logs``, with an
    evaluation (of two episodes) and a checkpoint every 200 timesteps, all kept.
    """
    confs = tmp_path_factory.mktemp("cases")

    def make(folder, case, **changes) -> TrainSettings:
        algo, env_id, extra = CASES[case]
        conf = confs / f"{case}.yml"
        if not conf.exists():
            conf.write_text(BASE + extra)
        values = dict(algo=algo, env_id=env_id, conf=conf, eval_freq=200, eval_episodes=2, save_freq=200, keep_checkpoints=10)
        return tiny_settings(folder, **{**values, **changes})

    return make


def crash_after(run_dir: str, env_id: str, timesteps: int) -> None:
    """Leave a run's folder as a crash just after its checkpoint at ``timesteps`` would: no later checkpoint,
    final model or final evaluation (the evaluations and episodes after it stay, as they would)."""
    layout = RunLayout(run_dir, env_id)
    for checkpoint in layout.checkpoints():
        if checkpoint.timesteps > timesteps:
            checkpoint.remove()
    for path in (layout.final_model, layout.final_evaluation, layout.vecnormalize):
        if os.path.exists(path):
            os.remove(path)


def parameters(path: str) -> dict[str, object]:
    """A model file's state dicts (policy and optimizers), flattened: ``policy.actor.mu.0.weight -> tensor``."""
    _, params, _ = load_from_zip_file(path, device="cpu")
    assert params is not None
    flat: dict[str, object] = {}

    def walk(prefix: str, value: object) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                walk(f"{prefix}.{key}", item)
        elif isinstance(value, (list, tuple)):
            for index, item in enumerate(value):
                walk(f"{prefix}.{index}", item)
        else:
            flat[prefix] = value

    walk("", params)
    return flat


def same(first: object, second: object) -> bool:
    if isinstance(first, th.Tensor):
        return isinstance(second, th.Tensor) and th.equal(first, second)
    return first == second


def assert_same_run(first: str, second: str, env_id: str) -> None:
    """Two run folders hold the same run: final and best models, replay buffers and statistics of the last
    checkpoint, evaluations, and training episodes (all but the wall-clock column)."""
    a, b = RunLayout(first, env_id), RunLayout(second, env_id)
    for model in (a.final_model, a.best_model):
        expected, actual = parameters(model), parameters(model.replace(first, second))
        assert expected.keys() == actual.keys()
        different = [name for name in expected if not same(expected[name], actual[name])]
        assert not different, f"{os.path.basename(model)}: {different}"
    last_a, last_b = a.checkpoints()[-1], b.checkpoints()[-1]
    assert last_a.timesteps == last_b.timesteps
    buffer_a, buffer_b = load_from_pkl(last_a.replay_buffer), load_from_pkl(last_b.replay_buffer)
    assert buffer_a.pos == buffer_b.pos
    for name in ("observations", "actions", "rewards", "next_observations", "dones", "timeouts"):
        np.testing.assert_array_equal(getattr(buffer_a, name), getattr(buffer_b, name), err_msg=name)
    if os.path.exists(last_a.vecnormalize):
        stats_a, stats_b = load_from_pkl(last_a.vecnormalize), load_from_pkl(last_b.vecnormalize)
        np.testing.assert_array_equal(stats_a.obs_rms.mean, stats_b.obs_rms.mean)
        np.testing.assert_array_equal(stats_a.ret_rms.var, stats_b.ret_rms.var)
    with np.load(a.evaluations) as expected, np.load(b.evaluations) as actual:
        assert expected.files == actual.files
        for name in expected.files:
            np.testing.assert_array_equal(expected[name], actual[name], err_msg=name)
    monitors = sorted(glob.glob(os.path.join(first, "*.monitor.csv")))
    assert monitors
    for monitor in monitors:
        expected, actual = (pd.read_csv(path, skiprows=1) for path in (monitor, monitor.replace(first, second)))
        pd.testing.assert_frame_equal(expected[["r", "l", "total_steps"]], actual[["r", "l", "total_steps"]])


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, case_settings):
    """One uninterrupted run of each case, made on first use."""
    folder = tmp_path_factory.mktemp("uninterrupted")
    runs: dict[str, str] = {}

    def run(case: str) -> str:
        if case not in runs:
            runs[case] = train(case_settings(folder, case)).run_dir
        return runs[case]

    return run


@pytest.mark.parametrize("case", list(CASES))
def test_a_run_resumed_after_a_crash_is_the_uninterrupted_run(uninterrupted, tmp_path, case, capsys, case_settings):
    expected = uninterrupted(case)
    env_id = CASES[case][1]
    run_dir = train(case_settings(tmp_path, case)).run_dir
    crash_after(run_dir, env_id, 200)
    capsys.readouterr()
    result = resume(run_dir)
    assert result.resumed_from == 200
    assert "new random stream" not in capsys.readouterr().out
    assert_same_run(expected, run_dir, env_id)


def test_environments_in_worker_processes_resume_as_well(uninterrupted, tmp_path, case_settings):
    # The records and replays go through SubprocVecEnv's pipes; the run is the one-process run of the same seed.
    expected = uninterrupted("td3-noisy-lidar-2-envs")
    env_id = CASES["td3-noisy-lidar-2-envs"][1]
    run_dir = train(case_settings(tmp_path, "td3-noisy-lidar-2-envs", vec_env="subproc")).run_dir
    crash_after(run_dir, env_id, 200)
    assert resume(run_dir).resumed_from == 200
    assert_same_run(expected, run_dir, env_id)


@pytest.mark.parametrize(
    "budget",
    [
        400,  # the last periodic checkpoint, taken inside the last step, is the run's last
        450,  # the run's last checkpoint is taken after its last step
    ],
)
def test_a_finished_run_trained_further_is_the_run_of_the_larger_budget(uninterrupted, tmp_path, budget, case_settings):
    # Nothing in the configuration depends on the budget (constant rates), so the runs may be the same.
    expected = uninterrupted("adc-pendulum")
    run_dir = train(case_settings(tmp_path, "adc-pendulum", n_timesteps=budget)).run_dir
    assert resume(run_dir, n_timesteps=600).resumed_from == budget
    assert_same_run(expected, run_dir, "Pendulum-v1")


def test_a_checkpoint_without_continuation_goes_on_from_a_new_random_stream(uninterrupted, tmp_path, capsys, case_settings):
    expected = uninterrupted("adc-pendulum")
    run_dir = train(case_settings(tmp_path, "adc-pendulum")).run_dir
    crash_after(run_dir, "Pendulum-v1", 200)
    checkpoint = RunLayout(run_dir, "Pendulum-v1").checkpoint(200)
    os.remove(checkpoint.continuation)
    write_manifest(checkpoint)  # as a second Ctrl-C's checkpoint is written: intact, without a continuation
    capsys.readouterr()
    assert resume(run_dir).resumed_from == 200
    out = " ".join(capsys.readouterr().out.split())
    assert "The checkpoint at timestep 200 has no continuation (taken by a second Ctrl-C, saved by an older version" in out
    assert "the run goes on from a new random stream." in out
    with pytest.raises(AssertionError, match=r"Pendulum-v1\.zip"):
        assert_same_run(expected, run_dir, "Pendulum-v1")


class CtrlCAt(BaseCallback):
    """Press Ctrl-C (SIGINT to this process) ``presses`` times when training reaches a timestep."""

    def __init__(self, at: int, presses: int = 1):
        super().__init__()
        self.at = at
        self.presses = presses

    def _on_step(self) -> bool:
        if self.num_timesteps == self.at:
            for _ in range(self.presses):
                os.kill(os.getpid(), signal.SIGINT)
        return True


def test_ctrl_c_stops_after_the_step_and_the_run_resumes_exactly(uninterrupted, tmp_path, capsys, case_settings):
    expected = uninterrupted("adc-pendulum")
    handler = signal.getsignal(signal.SIGINT)
    with pytest.raises(RunInterrupted) as interrupted:
        train(case_settings(tmp_path, "adc-pendulum"), callbacks=[CtrlCAt(250)])
    assert signal.getsignal(signal.SIGINT) is handler
    # Pressed during the callbacks of step 250 (after the checkpoint callback's turn): the run stops at the next.
    assert interrupted.value.timesteps == 251
    out = capsys.readouterr().out
    assert "Ctrl-C: stopping after this step with a checkpoint (Ctrl-C again stops at once)." in out
    assert "Interrupted: checkpoint at timestep 251 saved; resuming continues the same run." in out
    run_dir = interrupted.value.run_dir
    assert os.path.isfile(RunLayout(run_dir, "Pendulum-v1").checkpoint(251).continuation)
    assert resume(run_dir).resumed_from == 251
    assert "new random stream" not in capsys.readouterr().out
    assert_same_run(expected, run_dir, "Pendulum-v1")


def test_a_second_ctrl_c_stops_at_once_without_continuation(tmp_path, capsys, case_settings):
    handler = signal.getsignal(signal.SIGINT)
    with pytest.raises(RunInterrupted) as interrupted:
        train(case_settings(tmp_path, "adc-pendulum"), callbacks=[CtrlCAt(250, presses=2)])
    assert signal.getsignal(signal.SIGINT) is handler
    assert interrupted.value.timesteps == 250
    assert "Interrupted: checkpoint at timestep 250 saved.\n" in capsys.readouterr().out
    checkpoint = RunLayout(interrupted.value.run_dir, "Pendulum-v1").checkpoint(250)
    assert os.path.isfile(checkpoint.model)
    assert not os.path.exists(checkpoint.continuation)


def test_a_continuation_of_another_checkpoint_is_not_used(tmp_path, capsys, case_settings):
    run_dir = train(case_settings(tmp_path, "adc-pendulum", n_timesteps=400)).run_dir
    layout = RunLayout(run_dir, "Pendulum-v1")
    os.replace(layout.checkpoint(400).continuation, layout.checkpoint(200).continuation)
    write_manifest(layout.checkpoint(200))  # its manifest agrees: the continuation's own timestep refuses it
    crash_after(run_dir, "Pendulum-v1", 200)
    capsys.readouterr()
    assert resume(run_dir).resumed_from == 200
    assert "has no continuation" in capsys.readouterr().out


def test_frame_stacking_leaves_checkpoints_without_continuation(tmp_path, case_settings):
    # VecFrameStack keeps the last observations, which a continuation does not restore.
    conf = tmp_path / "td3.yml"
    conf.write_text(BASE.replace("n_timesteps: 600", "n_timesteps: 200") + "  frame_stack: 2\n")
    run_dir = train(case_settings(tmp_path, "adc-pendulum", algo="td3", conf_file=str(conf))).run_dir
    (checkpoint,) = RunLayout(run_dir, "Pendulum-v1").checkpoints()
    assert os.path.isfile(checkpoint.model)
    assert not os.path.exists(checkpoint.continuation)


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("sb3_adc/LidarObstacleCourseNoisy-v1", {"max_episode_steps": 40, "start_position_jitter": 0.2}),
        ("sb3_adc/LidarObstacleCourse-v1", {"max_episode_steps": 40, "robot": "wheeled"}),
        ("sb3_adc/HighwayObstacle-v0", {"max_episode_steps": 15}),
        ("Pendulum-v1", {"max_episode_steps": 40}),
    ],
)
def test_a_replayed_episode_continues_as_the_recorded_one(env_id, kwargs):
    """An environment made anew and given the record of another's episode in progress goes on as the other does,
    across the episode's end and the next reset."""
    recorded, replayed = (EpisodeRecorder(gym.make(env_id, **kwargs)) for _ in range(2))
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, size=(200, *recorded.action_space.shape))
    actions = actions.astype(recorded.action_space.dtype)
    recorded.reset(seed=5)
    for action in actions[:100]:  # a few episodes, the last one in progress
        _, _, terminated, truncated, _ = recorded.step(action)
        if terminated or truncated:
            recorded.reset()
    record = recorded.episode_record()
    assert record is not None
    assert record.actions
    replayed.replay_episode(record)
    for action in actions[100:]:
        first, second = recorded.step(action), replayed.step(action)
        np.testing.assert_array_equal(first[0], second[0])
        assert first[1:4] == second[1:4]
        if first[2] or first[3]:
            np.testing.assert_array_equal(recorded.reset()[0], replayed.reset()[0])
    recorded.close()
    replayed.close()
