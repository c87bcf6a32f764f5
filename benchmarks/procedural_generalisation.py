"""
Generalisation on the procedural lidar course, the Procgen/MetaDrive protocol: ADC, DDPG, TD3 and SAC train with
their shipped ``sb3_adc/LidarObstacleCourse-v1`` entries on the training layouts (layout seeds 0-999,999), then
each final model is scored on layouts and courses it never saw:

- the 100 held-out layouts (``TEST_LAYOUT_SEEDS``, 1,000,000-1,000,099), one episode each from the layout's start;
- every shipped course file (``envs/courses/``: the paper-style training loop and the unseen layouts, obstacle
  courses included), ``--course-episodes`` episodes each from a start jittered by 0.1 m and 10 degrees.

An episode is a success when it ends without a collision (``info["is_success"]``: 500 steps driven); a failed
episode records what the robot hit (a wall, a box, a cylinder or a wall stub: ``hit_*`` in ``success.csv``) and
whether the lidar showed the obstacle it hit in time (``hit_unseen``, see ``SIGHTING``). Per
run the success rate of each test set; per algorithm and test set, the IQM and mean of the runs' rates with 95%
stratified-bootstrap CIs (rliable), and the probability that ADC's rate exceeds each other algorithm's. The paths
of every run on the first ``--trajectory-layouts`` held-out layouts are kept (``trajectories.csv.gz``) and drawn.

``--configs FILE`` trains the algorithms a YAML file names, each with its overrides of its starting entry (a mapping
of algorithm to ``key: value`` overrides, checked as the engine checks ``-params``; ``n_timesteps`` sets the
budget); its results go to folders named after the file (``{env}_{file stem}``). ``--algos`` with it trains a subset
of the file's algorithms (the metadata records which). The starting entries (``STARTING_ENTRIES``,
``benchmarks/configs/starting_entries/``) are the ``-v1`` entries as shipped when the studies began, frozen: a
configuration file keeps meaning what it meant when it ran whatever the shipped entries become. Without
``--configs`` the algorithms train with the shipped entries as they are.

``--model best`` scores each run's ``best_model.zip`` instead of its final model: the model of the run's periodic
evaluation with the best mean return (SB3's ``EvalCallback`` rule, the RL Zoo's ``--load-best``: 20 evaluations of
5 episodes on training layouts, none of the test sets), the same rule for every algorithm. The runs are the same
(trained once, found finished); its results go to folders named ``..._best``.

``--actor-itself`` scores runs (ADC, TD3 or DDPG) that deploy an averaged actor (``actor_average_tau``) with the actor
itself, the average dropped: the same runs' control, since the average changes nothing that is learned; its results go to
folders named ``..._actor_itself``.

``--validation`` trains runs of their own (folders ``..._validation``) whose periodic evaluations select the model
on a validation split: 10 per run, each on the same 100 episodes of the validation layouts
(``VALIDATION_LAYOUT_SEEDS``, 2,000,000-2,000,099, which the tuning also used and the test sets do not), keeping as
``best_model.zip`` the model with the highest success rate (``best_model_metric="success"``); ``--model best``
then scores those models and ``--model final`` the final ones of the same runs, the test layouts and course files
unseen by either.

Training is ``sb3-adc benchmark``'s engine (resumable, one process per run, same seeds and evaluation for every
algorithm); the runs go to ``benchmarks/runs/procedural_generalisation/`` (not committed), the tables to
``benchmarks/results/procedural_generalisation/{name}/``. Each run is scored as soon as it is trained and kept in
the tables at once (those of an algorithm with seeds still to score in ``pending/``, out of the statistics); the
statistics and figures are written as soon as an algorithm's last run is scored, and when the invocation ends. A
re-run keeps the scored runs whose entry is current, without their run folders, and trains and scores the others
(:class:`ScoredRuns`; ``--rescore`` scores every run again). The figures go to
``docs/_static/benchmarks/procedural_generalisation_{name}.png`` (success rates) and
``docs/_static/benchmarks/procedural_trajectories_{name}.png`` (paths on held-out layouts).

Usage::

    python benchmarks/procedural_generalisation.py --workers 2                 # clean observations, kinematic robot
    python benchmarks/procedural_generalisation.py --env sb3_adc/LidarObstacleCourseNoisy-v1 --workers 2
    python benchmarks/procedural_generalisation.py --robot wheeled --workers 2   # the robot with dynamics
    python benchmarks/procedural_generalisation.py --configs benchmarks/configs/procedural_generalisation/FILE.yml --workers 2
    python benchmarks/procedural_generalisation.py --configs benchmarks/configs/procedural_generalisation/FILE.yml --model best
    python benchmarks/procedural_generalisation.py --quick                     # a smoke run
    python benchmarks/procedural_generalisation.py --replot                    # redraw the figures, no training
"""

from __future__ import annotations

import argparse
import functools
import gzip
import json
import os
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Collection
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
import pandas as pd
import torch as th
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from trajectories import plot_trajectories

from sb3_adc.common.actor_average import ActorAverageTD3Policy
from sb3_adc.common.atomic import write_atomically
from sb3_adc.config.experiment_config import ExperimentConfig
from sb3_adc.config.loader import HyperparamsError, load_hyperparams, read_yaml_file
from sb3_adc.experiment.benchmark import (
    EVALUATIONS_CSV,
    FINAL_CSV,
    BenchmarkSettings,
    RunOutcome,
    RunSpec,
    run_benchmark,
    run_script,
)
from sb3_adc.experiment.enjoy import load_model, load_run, model_path
from sb3_adc.experiment.invocations import INVOCATIONS_JSON, read_invocations
from sb3_adc.experiment.plots import plot_final_performance
from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc.experiment.results import read_table
from sb3_adc.experiment.settings import TrainSettings
from sb3_adc.experiment.statistics import final_performance, probability_of_improvement
from sb3_adc_envs.lidar_course import Course
from sb3_adc_envs.lidar_course.env import TEST_LAYOUT_SEEDS, VALIDATION_LAYOUT_SEEDS

ROOT = Path(__file__).resolve().parent
RUNS_DIR = ROOT / "runs" / "procedural_generalisation"
RESULTS_DIR = ROOT / "results" / "procedural_generalisation"
DOCS_STATIC = ROOT.parent / "docs" / "_static" / "benchmarks"
COURSES_DIR = ROOT.parent / "envs" / "courses"
#: The entries that the ``--configs`` files of this script and of ``budget_sweep.py`` override, one ``{algo}.yml``
#: per algorithm: the ``-v1`` entries as shipped when the studies began (30,000 steps, not tuned on ``-v1``), kept
#: apart from ``hyperparams/`` so that a configuration file means what it meant when it ran.
STARTING_ENTRIES = ROOT / "configs" / "starting_entries"

ALGOS = ["adc", "ddpg", "td3", "sac"]
SEEDS = list(range(1000, 1010))
HELD_OUT = "held-out layouts"
#: Start-pose jitter of the course-file episodes (a fixed start would repeat one episode).
COURSE_JITTER = {"start_position_jitter": 0.1, "start_heading_jitter_deg": 10.0}
#: Keywords of the training entries that only vary the start during training.
TRAINING_ONLY = ("start_position_jitter", "start_heading_jitter_deg")
TRAJECTORIES_CSV = "trajectories.csv.gz"
#: What a failed episode can have hit (``CourseSimulation.touching``): ``success.csv`` counts, per test set, the
#: failed episodes that ended touching each (an episode ending against a wall and a stub counts for both).
HITS = ("wall", "box", "cylinder", "stub")
#: When a failed episode's obstacle counts as unseen (``hit_unseen`` in ``success.csv``): no lidar ray hit it in the
#: scans from ``SIGHTING[1]`` to ``SIGHTING[0]`` steps before the contact, the metre of driving before it but the
#: last 0.5 m. Turning at its steering limit (6 degrees a step) the kinematic robot moves 0.21 m sideways in 6 steps,
#: its radius and a 6 cm post, and 0.52 m in 10: an obstacle first shown in the last 5 scans can hardly be avoided,
#: and a policy without memory cannot act on one it saw earlier and then lost between its rays.
SIGHTING = (6, 10)
#: What ``--model`` scores, as the metadata says it.
MODELS = {
    "final": "each run's final model",
    "best": "each run's best_model.zip: the periodic evaluation (20 per run, 5 episodes on training layouts) with the "
    "best mean return",
}
#: What ``--model best`` scores for runs trained with ``--validation``.
VALIDATION_BEST = (
    "each run's best_model.zip: the periodic evaluation (10 per run, the same 100 episodes on the validation layouts "
    "each time) with the highest success rate"
)
#: The periodic evaluations of ``--validation`` runs: how many per run, and their episodes.
VALIDATION_EVALUATIONS = 10
VALIDATION_EPISODES = 100
#: The table of the validation evaluations of ``--validation`` runs, beside their training record.
VALIDATION_CSV = "validation.csv"
#: The tables of a grid's scored runs, one or more rows per run (:class:`ScoredRuns`).
SUCCESS_CSV = "success.csv"
RUN_TABLES = (SUCCESS_CSV, FINAL_CSV, TRAJECTORIES_CSV)
#: The folder, beside a grid's tables, of the runs scored before every seed of their algorithm was (:class:`ScoredRuns`).
PENDING = "pending"
#: What a scored run's rows depend on besides its algorithm's entry (keys of ``metadata.json``): runs scored under
#: another protocol are scored again.
PROTOCOL = (
    "env",
    "robot",
    "model",
    "held_out_layouts",
    "trajectory_layouts",
    "courses",
    "course_episodes",
    "course_start_jitter",
)


def report(outcome: RunOutcome, done: int, total: int, by_folder: bool = False) -> None:
    """Progress: each finished run (``by_folder``: with its grid's folder, where several grids share one pool)."""
    final = "" if outcome.final is None else f" final return {outcome.final['mean_return']:.2f}"
    grid = f"{Path(outcome.log_folder).name}: " if by_folder else ""
    print(f"[{done}/{total}] {grid}{outcome.spec}: {outcome.status}{final}", flush=True)
    if outcome.status == "failed":
        print(outcome.error, flush=True)


def repository_path(path: str) -> str:
    """``path`` relative to the repository's root where it lies inside it, else absolute."""
    resolved = Path(path).resolve()
    return str(resolved.relative_to(ROOT.parent)) if resolved.is_relative_to(ROOT.parent) else str(resolved)


def read_configs(path: str) -> dict[str, dict[str, Any]]:
    """
    The configurations of a ``--configs`` file: configuration name (an algorithm, for this script) -> overrides of
    the starting entry (:func:`starting_entry`).

    :raises HyperparamsError: for a file that is not a non-empty mapping of names to mappings
    """
    content = read_yaml_file(path)
    if not isinstance(content, dict) or not content:
        raise HyperparamsError(path, None, "must be a non-empty mapping: configuration name -> {key: value} overrides")
    for name, overrides in content.items():
        if not isinstance(name, str) or not name.strip():
            raise HyperparamsError(path, None, f"configuration names must be non-empty strings, got {name!r}")
        if not isinstance(overrides, dict):
            raise HyperparamsError(path, name, f"must be a mapping of key: value overrides, got {type(overrides).__name__}")
    return content


def starting_entry(algo: str) -> str:
    """The hyperparameter file whose entries the configuration files override for ``algo`` (:data:`STARTING_ENTRIES`)."""
    return str(STARTING_ENTRIES / f"{algo}.yml")


class EpisodeOutcome(NamedTuple):
    """One scored episode (:func:`episode_outcome`)."""

    #: Whether it ended without a collision
    success: bool
    #: What the robot hit: the kinds of :data:`HITS` it touches where it stopped, each once (empty on success)
    hit: list[str]
    #: Whether it ended against an obstacle (not a wall of the corridor) that the lidar did not show it in time
    #: (:data:`SIGHTING`)
    unseen: bool = False


def episode_outcome(model: Any, env: gym.Env, **reset: Any) -> EpisodeOutcome:
    """
    Run one deterministic episode: whether it ended without a collision and, if not, what the robot hit and
    whether an obstacle it hit was unseen (no ray of the scans from ``SIGHTING[1]`` to ``SIGHTING[0]`` steps
    before the contact hit it).
    """
    observation, _ = env.reset(**reset)
    course_env: Any = env.unwrapped
    simulation = course_env.simulation
    late, early = SIGHTING
    # The bodies each scan's rays hit, the reset's first; the last `early + 1` are all the window needs.
    scans: deque[set[int]] = deque([set(simulation.ray_bodies)], maxlen=early + 1)
    while True:
        action, _ = model.predict(observation, deterministic=True)
        observation, _, terminated, truncated, info = env.step(action)
        scans.append(set(simulation.ray_bodies))
        if terminated or truncated:
            if info["is_success"]:
                return EpisodeOutcome(True, [])
            x, y, _ = course_env.pose
            touched = simulation.touched_bodies(x, y)
            obstacles = set(touched) & set(simulation.obstacle_ids)
            # scans[-1] is the scan at the contact, scans[-1 - k] the one k steps before it.
            seen = set().union(*list(scans)[: len(scans) - late])
            return EpisodeOutcome(False, sorted(set(simulation.body_kinds(touched))), bool(obstacles - seen))


def episode_success(model: Any, env: gym.Env, **reset: Any) -> bool:
    """Run one deterministic episode; whether it ended without a collision."""
    return episode_outcome(model, env, **reset).success


def layout_outcome(model: Any, env: gym.Env, layout_seed: int) -> EpisodeOutcome:
    """
    :func:`episode_outcome` on one procedural layout, the episode seeded by its layout seed (the noisy variants'
    observation noise too), so that scoring the same model again gives the same result.
    """
    return episode_outcome(model, env, seed=layout_seed, options={"layout_seed": layout_seed})


def layout_success(model: Any, env: gym.Env, layout_seed: int) -> bool:
    """:func:`layout_outcome`'s success alone."""
    return layout_outcome(model, env, layout_seed).success


def load_for_scoring(
    run_dir: str, which: str = "final", path: str | None = None
) -> tuple[TrainSettings, ExperimentConfig, Any, dict[str, Any]]:
    """
    A finished run's settings, entry and model on the CPU, and the ``gym.make`` keywords of its entry without the
    training-only start jitter.

    :param run_dir: The run's folder
    :param which: The run's model to load: ``final`` or ``best`` (see ``--model``), or another of
        :func:`~sb3_adc.experiment.enjoy.model_path`'s
    :param path: A zip file of the run to load instead (a checkpoint), ``which`` then not used
    """
    settings, config, layout = load_run(run_dir)
    if config.normalize is not None or config.frame_stack is not None:
        raise SystemExit(f"{run_dir}: scoring supports entries without `normalize` and `frame_stack`")
    model = load_model(config, path or model_path(layout, which)[0], device="cpu")
    kwargs = {key: value for key, value in config.env_kwargs.items() if key not in TRAINING_ONLY}
    return settings, config, model, kwargs


def training_record(
    output: Path,
    statuses: Counter[str],
    seconds: float,
    workers: int,
    algos: list[str] | None = None,
    runs_folder: Path | None = None,
    kept: bool = False,
    earlier: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """
    The training facts to record in ``output/metadata.json``: ``training_invocations``, one entry per invocation
    that trained or resumed runs of the grid (``wall_time_s``, ``workers``, ``algos`` and ``runs``: how many runs
    it trained, resumed or found finished), ``training_wall_time_s``, their total, and ``training_workers``, the
    last one's.

    Where the engine recorded the invocations (``invocations.json`` in the grid folders under ``runs_folder``,
    :mod:`sb3_adc.experiment.invocations`), they are the record, those stopped or killed before they finished
    included (``finished`` false, with ``started``). Entries of ``metadata.json`` from before that record are kept
    when the first recorded invocation found runs made before it. Without the record, from the counts of this
    invocation: an invocation that only scores (every run finished before) keeps the earlier record; one that
    trains some runs and finds others finished adds itself to it (an algorithm added to a ``--configs`` file); one
    that finds none of its runs finished replaces the earlier invocations of its algorithms and keeps those of the
    grid's other algorithms (trained by an invocation with other ``--algos``).

    Where the grid kept runs scored before (``kept``, :class:`ScoredRuns`), the invocations that trained them may
    be recorded in ``metadata.json`` only (their run folders gone with another machine): every earlier entry that
    the engine's record does not hold is kept.

    :param algos: The algorithms of this invocation (``None``: every algorithm of the grid)
    :param runs_folder: The folder of the grid's run folders (one per algorithm or configuration)
    :param kept: Whether the grid kept runs scored before
    :param earlier: The metadata holding the record before this invocation (default: ``output/metadata.json`` as it
        is); an invocation that writes its results more than once passes the one it started with
    """
    if earlier is None:
        previous = output / "metadata.json"
        earlier = json.loads(previous.read_text()) if previous.exists() else {}
    journals = sorted(runs_folder.glob(f"*/{INVOCATIONS_JSON}")) if runs_folder is not None else []
    recorded = read_invocations(str(path.parent) for path in journals)
    if recorded:
        first = recorded[0]["runs"]
        known = {entry["started"] for entry in recorded}
        if kept:
            before = [entry for entry in earlier.get("training_invocations", []) if entry.get("started") not in known]
        elif first.get("skipped", 0) + first.get("resumed", 0):
            before = [entry for entry in earlier.get("training_invocations", []) if "started" not in entry]
        else:
            before = []
        worked = [
            {key: entry[key] for key in ("started", "wall_time_s", "workers", "algos", "runs", "finished")}
            for entry in recorded
            if entry["runs"].get("trained", 0) + entry["runs"].get("resumed", 0) or not entry["finished"]
        ]
        invocations = [*before, *worked]
        return {
            "training_wall_time_s": round(sum(invocation["wall_time_s"] for invocation in invocations), 1),
            "training_workers": invocations[-1]["workers"] if invocations else workers,
            "training_invocations": invocations,
        }
    this = {
        "wall_time_s": round(seconds, 1),
        "workers": workers,
        **({"algos": list(algos)} if algos is not None else {}),
        "runs": dict(sorted(statuses.items())),
    }
    history = earlier.get("training_invocations")
    if history is None and "training_wall_time_s" in earlier:
        # Metadata written before the record was kept per invocation: one invocation.
        runs = earlier.get("training_runs", earlier.get("runs_this_invocation", {}))
        history = [
            {
                "wall_time_s": earlier["training_wall_time_s"],
                "workers": earlier.get("training_workers", earlier.get("workers", workers)),
                "runs": runs,
            }
        ]
    if history and algos is not None and "algos" in earlier:
        # Entries recorded without their algorithms belong to the algorithms of the metadata that holds them.
        history = [entry if "algos" in entry else {**entry, "algos": earlier["algos"]} for entry in history]
    if statuses["trained"] + statuses["resumed"]:
        previous_entries = history or []
        if not statuses["skipped"] and not kept:
            previous_entries = [
                entry for entry in previous_entries if algos is not None and not set(entry.get("algos", [])) <= set(algos)
            ]
        history = [*previous_entries, this]
    elif not history:
        history = [this]
    return {
        "training_wall_time_s": round(sum(invocation["wall_time_s"] for invocation in history), 1),
        "training_workers": history[-1]["workers"],
        "training_invocations": history,
    }


def layout_name(layout_seed: int) -> str:
    return f"layout {layout_seed}"


def held_out_courses(env_id: str, env_kwargs: dict[str, Any], layout_seeds: list[int]) -> dict[str, Course]:
    """The procedural courses of held-out layout seeds by name, as one environment builds them for its robot."""
    env = gym.make(env_id, **{**env_kwargs, "layout_seeds": TEST_LAYOUT_SEEDS})
    courses = {}
    for layout_seed in layout_seeds:
        env.reset(options={"layout_seed": layout_seed})
        courses[layout_name(layout_seed)] = env.unwrapped.course  # type: ignore[attr-defined]
    env.close()
    return courses


def score_policy(
    policy: Any,
    wrap: Callable[[gym.Env], gym.Env],
    env_id: str,
    env_kwargs: dict[str, Any],
    courses: list[str],
    course_episodes: int,
    n_layouts: int,
    trajectory_layouts: int,
) -> tuple[list[dict[str, Any]], list[pd.DataFrame]]:
    """
    The success rate of a policy (anything with SB3's ``predict``) on the first ``n_layouts`` held-out layouts and
    on each course file, and its paths on the first ``trajectory_layouts`` held-out layouts.

    :param wrap: The wrappers the policy was trained with (a run's ``config.wrap_env``)
    :param env_kwargs: ``gym.make`` keywords of every test environment
    :return: One row per test set (``test_set``, ``episodes``, ``successes``, ``success_rate``, ``hit_{kind}``
        for each of :data:`HITS`, ``hit_obstacle``: the failed episodes that ended against an obstacle, and
        ``hit_unseen``: those of them whose obstacle the lidar did not show in time, see :data:`SIGHTING`) and the
        paths
    """

    def row(test_set: str, outcomes: list[EpisodeOutcome]) -> dict[str, Any]:
        successes = [outcome.success for outcome in outcomes]
        return {
            "test_set": test_set,
            "episodes": len(successes),
            "successes": int(sum(successes)),
            "success_rate": float(np.mean(successes)),
            **{f"hit_{kind}": sum(kind in outcome.hit for outcome in outcomes) for kind in HITS},
            "hit_obstacle": sum(bool(set(outcome.hit) - {"wall"}) for outcome in outcomes),
            "hit_unseen": sum(outcome.unseen for outcome in outcomes),
        }

    rows = []
    env = wrap(gym.make(env_id, **{**env_kwargs, "layout_seeds": TEST_LAYOUT_SEEDS}))
    first = TEST_LAYOUT_SEEDS[0]
    outcomes: list[EpisodeOutcome] = []
    paths = []
    for k in range(n_layouts):
        outcomes.append(layout_outcome(policy, env, first + k))
        if k < trajectory_layouts:
            path = env.unwrapped.trajectory  # type: ignore[attr-defined]
            paths.append(
                pd.DataFrame(
                    {
                        "course": layout_name(first + k),
                        "step": np.arange(len(path)),
                        "x": path[:, 0].round(3),
                        "y": path[:, 1].round(3),
                        "success": outcomes[-1].success,
                    }
                )
            )
    rows.append(row(HELD_OUT, outcomes))
    env.close()
    for course in courses:
        env = wrap(gym.make(env_id, **{**env_kwargs, **COURSE_JITTER, "course": course}))
        rows.append(row(course, [episode_outcome(policy, env, seed=k) for k in range(course_episodes)]))
        env.close()
    return rows, paths


def scored_line(algo: str, seed: int, rows: list[dict[str, Any]]) -> str:
    """The progress line of a scored run: its success rate on each test set."""
    rates = ", ".join(f"{row['test_set']} {row['success_rate']:.2f}" for row in rows)
    return f"{algo} seed {seed}: {rates}"


def drop_actor_average(model: BaseAlgorithm) -> bool:
    """
    Make a model that deploys an averaged actor (``actor_average_tau`` of ADC's or TD3's policy) predict with the
    actor itself (the model is then for scoring only). Returns whether it had one.
    """
    policy = model.policy
    return isinstance(policy, ActorAverageTD3Policy) and policy.drop_actor_average()


def score_run(
    run_dir: str,
    algo: str,
    env_id: str,
    seed: int,
    courses: list[str],
    course_episodes: int,
    n_layouts: int,
    trajectory_layouts: int,
    which: str = "final",
    actor_itself: bool = False,
) -> tuple[list[dict[str, Any]], list[pd.DataFrame]]:
    """
    :func:`score_policy` for a finished run's model (``which``: ``final`` or ``best``, see ``--model``), its rows and
    paths labelled with the run; with ``actor_itself`` (``--actor-itself``), the model's averaged actor dropped.
    """
    th.set_num_threads(1)
    _, config, model, kwargs = load_for_scoring(run_dir, which)
    if actor_itself and not drop_actor_average(model):
        raise SystemExit(f"--actor-itself: the model of {run_dir} does not deploy an averaged actor")
    rows, paths = score_policy(model, config.wrap_env, env_id, kwargs, courses, course_episodes, n_layouts, trajectory_layouts)
    run = {"algo": algo, "env": env_id, "seed": seed}
    return [run | row for row in rows], [path.assign(algo=algo, seed=seed)[["algo", "seed", *path.columns]] for path in paths]


def periodic_evaluations(validation: bool, n_timesteps: int, validation_episodes: int = VALIDATION_EPISODES) -> dict[str, Any]:
    """
    The periodic evaluations of the runs (keywords of ``BenchmarkSettings``): 20 of 5 episodes on training layouts,
    SB3's rule picking ``best_model.zip``; with ``validation`` (``--validation``), :data:`VALIDATION_EVALUATIONS` on
    the same ``validation_episodes`` episodes of the validation layouts, the highest success rate picking it.

    :param validation: Whether the runs select their model on the validation layouts
    :param n_timesteps: The runs' budget
    :param validation_episodes: Episodes of each validation evaluation
    """
    if not validation:
        return {"eval_episodes": 5}
    return {
        "eval_freq": max(n_timesteps // VALIDATION_EVALUATIONS, 1),
        "eval_episodes": validation_episodes,
        "eval_env_kwargs": {"layout_seeds": list(VALIDATION_LAYOUT_SEEDS)},
        "best_model_metric": "success",
    }


def validation_table(evaluations: pd.DataFrame) -> pd.DataFrame:
    """
    The validation evaluations of ``--validation`` runs (``validation.csv``): per run and evaluation its success rate
    and mean return on the validation episodes, from which the engine chose ``best_model.zip``
    (``best_model_metric="success"``, :class:`~sb3_adc.experiment.callbacks.PeriodicEvalCallback`).

    :param evaluations: The runs' ``evaluations.csv`` (the benchmark engine's table)
    """
    return evaluations[["algo", "seed", "timesteps", "success_rate", "mean_return", "n_episodes"]].reset_index(drop=True)


def robot_overrides(
    algo: str, env_id: str, robot: str, overrides: dict[str, Any] | None = None, conf_file: str | None = None
) -> dict[str, Any]:
    """
    ``overrides`` (of a ``--configs`` file) with another robot: the ``env_kwargs`` they give, or the entry's (of
    ``conf_file``, ``None``: the shipped one), with ``robot`` (an override replaces the whole ``env_kwargs``).
    """
    overrides = dict(overrides or {})
    if robot == "kinematic":
        return overrides
    env_kwargs = overrides.get("env_kwargs", load_hyperparams(algo, env_id, conf_file).env_kwargs)
    return {**overrides, "env_kwargs": {**env_kwargs, "robot": robot}}


def trained_entry(
    algo: str, env_id: str, conf_file: str | None, overrides: dict[str, Any], n_timesteps: int | None
) -> dict[str, Any]:
    """
    The hyperparameters a grid's runs of ``algo`` train with, as plain data (what each run's ``config.yml`` holds):
    the entry of ``conf_file`` (``None``: the shipped one) with ``overrides`` and the budget ``n_timesteps``
    (``None``: the entry's). Recorded as ``entries`` in the grid's ``metadata.json`` (:func:`stale_entries`).
    """
    resolved = load_hyperparams(algo, env_id, conf_file, overrides, n_timesteps)
    return yaml.safe_load(yaml.safe_dump(resolved.saved))


def stale_entries(metadata: dict[str, Any], algos: Collection[str] | None = None) -> list[str]:
    """
    The algorithms of a scored grid whose recorded ``entries`` differ from what the grid's command trains today: an
    entry (shipped, or a starting entry of ``--configs``) changed after the grid ran, so its numbers are no longer
    what the command reproduces. Grids scored before ``entries`` was recorded have none to check.

    :param metadata: The grid's ``metadata.json``
    :param algos: The recorded algorithms to check (``None``: all of them)
    """
    configs = metadata.get("configs")
    budgets = metadata["n_timesteps"] if isinstance(metadata["n_timesteps"], dict) else {}
    stale = []
    for algo, recorded in metadata.get("entries", {}).items():
        if algos is not None and algo not in algos:
            continue
        conf_file = starting_entry(algo) if configs is not None else None
        overrides = robot_overrides(algo, metadata["env"], metadata["robot"], (configs or {}).get(algo), conf_file)
        budget = budgets.get(algo)
        if trained_entry(algo, metadata["env"], conf_file, overrides, budget if isinstance(budget, int) else None) != recorded:
            stale.append(algo)
    return stale


def write_csv(table: pd.DataFrame, path: Path) -> None:
    """
    Write a table atomically; a ``.gz`` one compressed without a timestamp, so that the same rows give the same
    bytes and rewriting an unchanged table leaves it unchanged.
    """
    data = table.to_csv(index=False).encode()
    if path.name.endswith(".gz"):
        data = gzip.compress(data, mtime=0)
    write_atomically(path, lambda stream: stream.write(data), binary=True)


def read_if_present(path: Path) -> pd.DataFrame | None:
    """A table of runs (:func:`~sb3_adc.experiment.results.read_table`), ``None`` where there is none."""
    return read_table(path) if path.exists() else None


def runs_of(table: pd.DataFrame) -> set[tuple[str, int]]:
    """The runs (algorithm, seed) with rows in a table of runs."""
    return {(str(algo), int(seed)) for algo, seed in zip(table["algo"], table["seed"], strict=True)}


def select_runs(table: pd.DataFrame, runs: set[tuple[str, int]], keep: bool = True) -> pd.DataFrame:
    """The rows of a table of runs that are those of ``runs`` (``keep``) or of the other runs."""
    mask = [((str(algo), int(seed)) in runs) == keep for algo, seed in zip(table["algo"], table["seed"], strict=True)]
    return table[np.array(mask, dtype=bool)].reset_index(drop=True)


def replace_runs(table: pd.DataFrame | None, new: pd.DataFrame, algos: list[str]) -> pd.DataFrame:
    """
    ``table`` with the rows of the runs of ``new`` replaced by ``new``'s, sorted by algorithm (in the order of
    ``algos``) and seed, each run's rows in their order.
    """
    kept = select_runs(table, runs_of(new), keep=False) if table is not None else new.iloc[:0]
    merged = pd.concat([frame for frame in (kept, new) if not frame.empty], ignore_index=True)
    rank = merged["algo"].map({algo: position for position, algo in enumerate(algos)})
    return merged.assign(_rank=rank).sort_values(["_rank", "seed"], kind="stable").drop(columns="_rank").reset_index(drop=True)


class ScoredRuns:
    """
    The runs of a grid scored so far, kept with its results: a grid trained over several invocations, sessions or
    machines never trains or scores a finished run twice, and loses none when the runs' folders (not committed) are
    gone. ``success.csv``, ``final.csv`` and ``trajectories.csv.gz`` of the results folder hold the runs of the
    algorithms whose every seed is scored, the only ones the statistics use; ``pending/`` holds the same tables
    for the runs of the other algorithms. ``metadata.json`` records the entry of every algorithm with scored runs
    (``entries``) and the seeds scored of the others (``pending_runs``). Each run is written as soon as it is
    scored.

    A run found there is kept when its algorithm's entry is the one the grid trains today and the scoring protocol
    (:data:`PROTOCOL`) is the same; otherwise it is trained (or found finished on disk) and scored again.

    :param output: The grid's results folder
    :param protocol: The grid's values of :data:`PROTOCOL`
    :param entries: The entries this invocation trains (:func:`trained_entry`) by algorithm; the recorded ones of
        the grid's other algorithms are kept where :func:`stale_entries` finds them current
    :param seeds: The grid's seeds
    :param rescore: Keep no run (``--rescore``)
    """

    def __init__(
        self,
        output: Path,
        protocol: dict[str, Any],
        entries: dict[str, dict[str, Any]],
        seeds: list[int],
        rescore: bool = False,
    ) -> None:
        self.output = output
        self.seeds = seeds
        path = output / "metadata.json"
        self.metadata: dict[str, Any] = json.loads(path.read_text()) if path.exists() else {}
        recorded: dict[str, Any] = self.metadata.get("entries", {})
        same = bool(recorded) and not rescore and all(self.metadata.get(key) == protocol[key] for key in PROTOCOL)
        # The entries this invocation trains are compared as resolved; only the others' are resolved again here.
        others = [algo for algo in recorded if algo not in entries]
        stale = set(stale_entries(self.metadata, others)) if same and others else set()
        valid = [
            algo
            for algo, entry in recorded.items()
            if same and (entries[algo] == entry if algo in entries else algo not in stale)
        ]
        #: The entry of each algorithm of the grid, in its order: those with runs kept first
        self.entries = {algo: recorded[algo] for algo in valid} | {
            algo: entry for algo, entry in entries.items() if algo not in valid
        }
        tables = {}
        for name in RUN_TABLES:
            found = [
                table
                for table in (read_if_present(output / name), read_if_present(output / PENDING / name))
                if table is not None
            ]
            table = pd.concat(found, ignore_index=True) if found else pd.DataFrame(columns=["algo", "seed"])
            tables[name] = table[table["algo"].isin(valid) & table["seed"].isin(seeds)]
        # A run counts as scored where both its scores and its final evaluation are there.
        runs = runs_of(tables[SUCCESS_CSV]) & runs_of(tables[FINAL_CSV])
        self.tables = {name: select_runs(table, runs) for name, table in tables.items()}
        #: How many runs were found scored
        self.kept = len(runs)

    def scored(self, algo: str) -> list[int]:
        """The seeds of ``algo`` scored so far."""
        table = self.tables[SUCCESS_CSV]
        return sorted({int(seed) for seed in table.loc[table["algo"] == algo, "seed"]})

    def missing(self, algo: str) -> list[int]:
        """The seeds of ``algo`` to train (or find finished) and score."""
        scored = set(self.scored(algo))
        return [seed for seed in self.seeds if seed not in scored]

    def complete(self) -> list[str]:
        """The algorithms whose every seed is scored, in the grid's order."""
        return [algo for algo in self.entries if not self.missing(algo)]

    def pending(self) -> dict[str, list[int]]:
        """The seeds scored of the algorithms with some but not all of their seeds scored."""
        return {algo: seeds for algo in self.entries if (seeds := self.scored(algo)) and self.missing(algo)}

    def table(self, name: str, algos: list[str]) -> pd.DataFrame:
        """The rows of table ``name`` of the runs of ``algos``."""
        table = self.tables[name]
        return table[table["algo"].isin(algos)].reset_index(drop=True)

    def add(self, final: dict[str, Any], rows: list[dict[str, Any]], paths: list[pd.DataFrame]) -> None:
        """Keep a scored run (its final evaluation, its scores and its paths, each of them labelled with the run) and
        write the tables."""
        new = {FINAL_CSV: pd.DataFrame([final]), SUCCESS_CSV: pd.DataFrame(rows), TRAJECTORIES_CSV: pd.concat(paths)}
        for name, table in self.tables.items():
            self.tables[name] = replace_runs(table, new[name], list(self.entries))
        self.write()

    def write(self, metadata: dict[str, Any] | None = None) -> None:
        """
        Write the tables (the complete algorithms' runs in the results folder, the others' in ``pending/``) and
        ``metadata.json``: ``metadata`` (default: :attr:`metadata`, the one found or the one the grid set) with
        ``entries`` and ``pending_runs``.
        """
        complete, pending = self.complete(), self.pending()
        for name in RUN_TABLES:
            for folder, algos in ((self.output, complete), (self.output / PENDING, list(pending))):
                table = self.table(name, algos)
                if not table.empty:
                    folder.mkdir(parents=True, exist_ok=True)
                    write_csv(table, folder / name)
                elif (folder / name).exists():
                    (folder / name).unlink()
        if (self.output / PENDING).exists() and not any((self.output / PENDING).iterdir()):
            (self.output / PENDING).rmdir()
        scored = [algo for algo in self.entries if self.scored(algo)]
        metadata = {key: value for key, value in (metadata or self.metadata).items() if key != "pending_runs"}
        metadata["entries"] = {algo: self.entries[algo] for algo in scored}
        if pending:
            metadata["pending_runs"] = pending
        self.metadata = metadata
        text = json.dumps(metadata, indent=2) + "\n"
        write_atomically(self.output / "metadata.json", lambda stream: stream.write(text))


def as_scores(scores: pd.DataFrame) -> pd.DataFrame:
    """The success rates in the statistics' layout: each test set as an ``env``, each rate as a ``mean_return``."""
    return scores.drop(columns="env").rename(columns={"test_set": "env", "success_rate": "mean_return"})


def plot(scores: pd.DataFrame, path: Path, reps: int) -> pd.DataFrame:
    """IQM and mean success rate per algorithm, one panel per test set, with 95% CIs."""
    table = as_scores(scores)
    performance = final_performance(table, reps=reps)
    plot_final_performance(performance, str(path), quantity="success rate (share of collision-free episodes)")
    return performance


def plot_paths(trajectories: pd.DataFrame, env_id: str, robot: str, path: Path, which: str = "final") -> None:
    """Every run's path on the held-out layouts of ``trajectories``, one row per algorithm."""
    env_kwargs = {} if robot == "kinematic" else {"robot": robot}
    seeds = sorted({int(name.split()[-1]) for name in trajectories["course"]})
    courses = held_out_courses(env_id, env_kwargs, seeds)
    title = f"{env_id} ({robot} robot): {which} models on held-out layouts, one path per run"
    plot_trajectories(trajectories, courses, str(path), title=title)


def write_statistics(ledger: ScoredRuns, env_id: str, robot: str, which: str, reps: int, figures: str | None) -> list[str]:
    """
    Write the statistics of the grid's complete algorithms (:meth:`ScoredRuns.complete`, their every seed scored) to
    its results folder: ``success_rates.csv`` and ``success_rates.md`` (IQM and mean success rate per algorithm and
    test set, 95% stratified-bootstrap CIs), ``probability_of_improvement.csv`` and the figures of the success rates
    and of the paths on held-out layouts.

    :param which: The model scored (``final`` or ``best``), named in the paths' figure
    :param reps: Bootstrap replications
    :param figures: The name the figures take in ``docs/_static/benchmarks/`` (``None``: left in the results folder)
    :return: The lines of ``success_rates.md``
    """
    output = ledger.output
    algos = ledger.complete()
    scores = ledger.table(SUCCESS_CSV, algos)
    paths_figure = output / "trajectories.png"
    plot_paths(ledger.table(TRAJECTORIES_CSV, algos), env_id, robot, paths_figure, which)
    figure = output / "success_rates.png"
    performance = plot(scores, figure, reps)
    performance.rename(columns={"env": "test_set"}).to_csv(output / "success_rates.csv", index=False)
    improvement = probability_of_improvement(as_scores(scores), reps=reps)
    improvement.to_csv(output / "probability_of_improvement.csv", index=False)
    if figures is not None:
        DOCS_STATIC.mkdir(parents=True, exist_ok=True)
        os.replace(figure, DOCS_STATIC / f"procedural_generalisation_{figures}.png")
        os.replace(paths_figure, DOCS_STATIC / f"procedural_trajectories_{figures}.png")
    lines = ["| test set | algorithm | runs | success rate IQM [95% CI] | mean [95% CI] |", "|---|---|---:|---|---|"]
    for row in performance.itertuples(index=False):
        lines.append(
            f"| {row.env} | {row.algo} | {row.n_runs} | {row.iqm:.2f} [{row.iqm_ci_low:.2f}, {row.iqm_ci_high:.2f}] "
            f"| {row.mean:.2f} [{row.mean_ci_low:.2f}, {row.mean_ci_high:.2f}] |"
        )
    (output / "success_rates.md").write_text("\n".join(lines) + "\n")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="sb3_adc/LidarObstacleCourse-v1", help="the procedural environment id")
    parser.add_argument("--robot", choices=["kinematic", "wheeled"], default="kinematic", help="robot model")
    parser.add_argument("--algos", nargs="+", choices=ALGOS, default=ALGOS)
    parser.add_argument(
        "--configs", help="YAML file: algorithm -> overrides of its starting entry (the algorithms trained; see above)"
    )
    parser.add_argument("--workers", type=int, default=1, help="parallel runs and scorings")
    parser.add_argument("--course-episodes", type=int, default=10, help="jittered episodes per course file")
    parser.add_argument("--reps", type=int, default=5000, help="bootstrap replications")
    parser.add_argument("--trajectory-layouts", type=int, default=4, help="held-out layouts whose paths are drawn")
    parser.add_argument("--quick", action="store_true", help="smoke run: 2 seeds, 600 steps, 3 layouts, 1 course")
    parser.add_argument("--replot", action="store_true", help="redraw the figure from the committed success.csv")
    parser.add_argument(
        "--model", choices=list(MODELS), default="final", help="which model of each run is scored (default: final)"
    )
    parser.add_argument(
        "--validation",
        action="store_true",
        help="runs of their own that select best_model.zip by success on the validation layouts (see above)",
    )
    parser.add_argument(
        "--actor-itself", action="store_true", help="score ADC's actor itself instead of its averaged actor (see above)"
    )
    parser.add_argument(
        "--rescore", action="store_true", help="score every run again instead of keeping the runs scored before (see above)"
    )
    args = parser.parse_args()
    if min(args.workers, args.course_episodes, args.reps, args.trajectory_layouts) < 1:
        parser.error("--workers, --course-episodes, --reps and --trajectory-layouts must be >= 1")
    th.set_num_threads(1)
    configs: dict[str, dict[str, Any]] = {algo: {} for algo in args.algos}
    if args.configs:
        try:
            configs = read_configs(args.configs)
        except (OSError, HyperparamsError) as error:
            parser.error(f"--configs: {error}")
        unknown = sorted(set(configs) - set(ALGOS))
        if unknown:
            parser.error(f"--configs: {', '.join(unknown)} not among the algorithms {', '.join(ALGOS)}")
        if args.algos != ALGOS:  # a subset of the file's configurations, in the file's order
            missing = [algo for algo in args.algos if algo not in configs]
            if missing:
                parser.error(f"--algos: {', '.join(missing)} not in {args.configs}, which names {', '.join(configs)}")
            configs = {algo: overrides for algo, overrides in configs.items() if algo in args.algos}
        args.algos = list(configs)
    budgets = {algo: configs[algo].pop("n_timesteps", None) for algo in args.algos}
    stem = f"_{Path(args.configs).stem}" if args.configs else ""
    robot = "" if args.robot == "kinematic" else f"_{args.robot}"
    grid = args.env.split("/")[-1] + robot + stem
    quick = "_quick" if args.quick else ""
    runs_name = grid + ("_validation" if args.validation else "") + quick
    name = runs_name.removesuffix(quick) + ("" if args.model == "final" else f"_{args.model}")
    name += ("_actor_itself" if args.actor_itself else "") + quick
    seeds, n_layouts, reps = SEEDS, len(range(*TEST_LAYOUT_SEEDS)), args.reps
    courses = sorted(path.stem for path in COURSES_DIR.glob("*.yml"))
    trajectory_layouts = args.trajectory_layouts
    if args.quick:
        seeds, n_layouts, courses, reps = seeds[:2], 3, courses[:1], 200
        budgets = dict.fromkeys(args.algos, 600)
    trajectory_layouts = min(trajectory_layouts, n_layouts)
    folder = RUNS_DIR / runs_name  # the same runs whichever model is scored
    output = RESULTS_DIR / name
    if args.replot:
        figure = DOCS_STATIC / f"procedural_generalisation_{name}.png"
        plot(read_table(output / SUCCESS_CSV), figure, reps)
        print(f"wrote {figure}")
        if (output / TRAJECTORIES_CSV).exists():
            paths_figure = DOCS_STATIC / f"procedural_trajectories_{name}.png"
            plot_paths(read_table(output / TRAJECTORIES_CSV), args.env, args.robot, paths_figure, args.model)
            print(f"wrote {paths_figure}")
        return
    output.mkdir(parents=True, exist_ok=True)
    conf_folder = str(STARTING_ENTRIES) if args.configs else None
    overrides = {
        algo: robot_overrides(algo, args.env, args.robot, configs[algo], starting_entry(algo) if args.configs else None)
        for algo in args.algos
    }
    # What the runs train with (the engine refuses runs on disk made with anything else: RunSettingsMismatch).
    entries = {
        algo: trained_entry(algo, args.env, starting_entry(algo) if args.configs else None, overrides[algo], budgets[algo])
        for algo in args.algos
    }
    model = VALIDATION_BEST if args.validation and args.model == "best" else MODELS[args.model]
    protocol = {
        "env": args.env,
        "robot": args.robot,
        "model": model,
        "held_out_layouts": [TEST_LAYOUT_SEEDS[0], TEST_LAYOUT_SEEDS[0] + n_layouts - 1],
        "trajectory_layouts": trajectory_layouts,
        "courses": courses,
        "course_episodes": args.course_episodes,
        "course_start_jitter": COURSE_JITTER,
    }
    ledger = ScoredRuns(output, protocol, entries, seeds, rescore=args.rescore)
    if ledger.kept:
        print(f"{ledger.kept} runs scored before are kept ({output}); the others are trained and scored", flush=True)
    # What the grid is, recorded with its runs as each is kept: this invocation's budgets and configurations, and
    # the recorded ones of the grid's other algorithms.
    earlier = ledger.metadata
    grid_algos = list(ledger.entries)
    recorded_budgets = earlier.get("n_timesteps")
    earlier_budgets: dict[str, Any] = recorded_budgets if isinstance(recorded_budgets, dict) else {}
    budget_record = {**earlier_budgets, **{algo: budget or "the entry's n_timesteps" for algo, budget in budgets.items()}}
    all_configs = {**earlier.get("configs", {}), **configs}
    description = {
        "env": args.env,
        "robot": args.robot,
        "seeds": seeds,
        "n_timesteps": (
            {algo: budget_record[algo] for algo in grid_algos if algo in budget_record}
            if args.configs or args.quick
            else "each entry's n_timesteps"
        ),
        "hyperparams": (
            f"starting entries ({repository_path(str(STARTING_ENTRIES))}/{{algo}}.yml) with the overrides of "
            f"{repository_path(args.configs)}"
            if args.configs
            else "shipped (hyperparams/{algo}.yml)"
        ),
        **({"configs": {algo: all_configs[algo] for algo in grid_algos if algo in all_configs}} if args.configs else {}),
        "entries": ledger.entries,
        "model": model,
        **({"validation": periodic_evaluations(True, 0)} if args.validation else {}),
        **({"actor_itself": True} if args.actor_itself else {}),
        **{key: value for key, value in protocol.items() if key not in ("env", "robot", "model")},
    }
    ledger.metadata = {**earlier, **description}
    start = time.perf_counter()
    evaluations: list[pd.DataFrame] = []
    statuses = Counter[str]()
    scoring_start, scored = None, 0
    # The training record before this invocation (it rewrites the metadata each time it writes the results).
    record_path = RESULTS_DIR / runs_name / "metadata.json"
    record_before = json.loads(record_path.read_text()) if record_path.exists() else {}

    def training_so_far() -> dict[str, Any]:
        """The training record of the grid up to now (:func:`training_record`)."""
        elapsed = time.perf_counter() - start
        return training_record(
            RESULTS_DIR / runs_name, statuses, elapsed, args.workers, args.algos, folder, bool(ledger.kept), record_before
        )

    def write_results() -> None:
        """The statistics of the grid's complete algorithms and ``metadata.json`` with the training so far: written
        when an algorithm's last run is scored (the results folder never holds scored runs that its statistics
        leave out) and when the invocation ends."""
        scoring_s = time.perf_counter() - scoring_start if scoring_start is not None else None
        # The training of the grid (recorded beside its final models when `--model best` finds every run finished).
        training = training_so_far()
        if args.validation and evaluations:  # beside the training record: the runs' evaluations, whichever model is scored
            path = RESULTS_DIR / runs_name / VALIDATION_CSV
            new = validation_table(pd.concat(evaluations, ignore_index=True))
            write_csv(replace_runs(read_if_present(path), new, list(ledger.entries)), path)
        lines = write_statistics(ledger, args.env, args.robot, args.model, reps, None if args.quick else name)
        metadata = {
            "env": args.env,
            "robot": args.robot,
            "algos": ledger.complete(),
            **{key: value for key, value in description.items() if key not in ("env", "robot")},
            **training,
            "runs_this_invocation": dict(sorted((statuses + Counter(kept=ledger.kept)).items())),
            "scoring_wall_time_s": round(scoring_s, 1) if scoring_s is not None else earlier.get("scoring_wall_time_s"),
            "workers": args.workers,
            "bootstrap_reps": reps,
            **machine_metadata(),
        }
        ledger.write(metadata)
        print("\n".join(lines), flush=True)

    written = False  # whether the results written last are current
    with ProcessPoolExecutor(max_workers=args.workers) as scoring:
        # Each run is scored as soon as it is trained (or found finished), beside the training, and kept (written)
        # as soon as it is scored, by the scoring's callback thread; each of `writes` completes once its run is written.
        lock, writes = threading.Lock(), list[Future[None]]()

        def keep(final: dict[str, Any], done: Future[Any], written: Future[None]) -> None:
            nonlocal scored
            try:
                rows, paths = done.result()
                with lock:
                    scored += 1
                    print(f"scored {scored}: {scored_line(final['algo'], final['seed'], rows)}", flush=True)
                    # The training so far is kept with the run: the invocations' journals live in the run folders,
                    # which go with the machine, while a kept run's results are committed (`training_record`
                    # keeps the invocations metadata.json holds that no journal here does).
                    ledger.metadata = {**ledger.metadata, **training_so_far()}
                    ledger.add(final, rows, paths)
                written.set_result(None)
            except BaseException as error:  # raised by the main thread (`collect`)
                written.set_exception(error)

        def collect() -> None:
            for written in writes:
                written.result()

        def on_run(outcome: RunOutcome, done: int, total: int) -> None:
            nonlocal scoring_start
            report(outcome, done, total)
            if outcome.final is None:
                return
            spec = outcome.spec
            job = (
                RunSpec(spec.algo, args.env, spec.seed).run_dir(str(folder / spec.algo)),
                spec.algo,
                args.env,
                spec.seed,
                courses,
                args.course_episodes,
                n_layouts,
                trajectory_layouts,
                args.model,
                args.actor_itself,
            )
            scoring_start = scoring_start or time.perf_counter()
            written = Future[None]()
            writes.append(written)
            scoring.submit(score_run, *job).add_done_callback(functools.partial(keep, outcome.final, written=written))

        for algo in args.algos:
            missing = ledger.missing(algo)
            if not missing:
                continue
            written = False
            settings = BenchmarkSettings(
                algos=[algo],
                env_ids=[args.env],
                seeds=missing,
                log_folder=str(folder / algo),
                n_timesteps=budgets[algo],
                overrides=overrides[algo],
                conf_folder=conf_folder,
                final_eval_episodes=20,
                device="cpu",
                **periodic_evaluations(
                    args.validation, entries[algo]["n_timesteps"], VALIDATION_EPISODES if not args.quick else 3
                ),
            )
            result = run_benchmark(settings, workers=args.workers, report=on_run)
            statuses.update(outcome.status for outcome in result.outcomes)
            table = read_table(result.tables[EVALUATIONS_CSV])
            evaluations.append(table[table["seed"].isin(missing)])
            collect()  # the algorithm's runs scored: its statistics before the next algorithm trains
            if result.failures:
                raise SystemExit(f"{len(result.failures)} runs of {algo} failed; re-run to retry them")
            if algo in ledger.complete():
                write_results()
                written = True
    if not written:
        write_results()


if __name__ == "__main__":
    run_script(main)
