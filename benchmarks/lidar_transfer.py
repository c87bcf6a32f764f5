"""Learnability of the lidar obstacle course and transfer of the trained policy to unseen layouts.

Trains an agent (ADC by default) on ``sb3_adc/LidarObstacleCourse-v0`` (the ``training`` course) with the
hyperparameters of ``hyperparams/<algo>.yml`` (or ``--conf-file``), then evaluates it:

1. on the training course from its exact start pose (the paper's claim: 500 steps without a collision);
2. on the training course and on every unseen layout, ``--episodes`` episodes each with a jittered start
   pose (0.1 m along x and y, 10 degrees): collision-free episodes out of N, and the laps driven.

Training runs on the engine (``sb3_adc.experiment.train``: the RL Zoo's ``ExperimentManager``), which shows a
progress bar and checkpoints (model and replay buffer) every ``--eval-freq`` steps in ``--run-dir``; running the
script again resumes from the last checkpoint. At each checkpoint the policy is
evaluated on the training course (``--eval-episodes`` jittered episodes); the best of these evaluations is
kept as ``best_model.zip``. The unseen layouts are never used to select a model. Both the best and the final
model are evaluated.

Results: ``<out>/<tag>/summary.json``, ``episodes.csv``, ``learning_curve.csv`` and ``best_model.zip``,
``<out>/runs.csv`` and ``<out>/transfer_table.csv`` (every run of ``<out>`` in one table), and the figures
``docs/_static/envs/lidar_transfer_trajectories[_<tag>].png`` and ``docs/_static/envs/lidar_learning_curves.png``.

Usage::

    python benchmarks/lidar_transfer.py                               # ADC, hyperparams/adc.yml
    python benchmarks/lidar_transfer.py --algo ddpg --seed 1
    python benchmarks/lidar_transfer.py --conf-file hyperparams/paper/adc.yml --tag adc_table2_seed0
    python benchmarks/lidar_transfer.py --tables-only                 # rebuild runs.csv / transfer_table.csv
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

import sb3_adc
from sb3_adc.common.atomic import atomic_path, write_atomically
from sb3_adc.config.loader import load_hyperparams
from sb3_adc.experiment import RunLayout, TrainSettings, resume, train
from sb3_adc_envs.lidar_course import Course, geometry, load_course
from sb3_adc_envs.lidar_course.env import LidarObstacleCourseEnv

ENV_ID = "sb3_adc/LidarObstacleCourse-v0"
TRAINING_COURSE = "training"
UNSEEN_COURSES = ("unseen_narrow", "unseen_wide", "unseen_zigzag", "unseen_arena")
#: Start-pose jitter of every evaluation episode but the exact-start one.
EVAL_JITTER: dict[str, Any] = {"start_position_jitter": 0.1, "start_heading_jitter_deg": 10.0}
MAX_STEPS = 500
ROOT = Path(__file__).resolve().parent.parent
FIGURES_DIR = ROOT / "docs" / "_static" / "envs"


@dataclass
class Episode:
    """One evaluation episode."""

    course: str
    seed: int
    jittered: bool
    steps: int
    collision: bool
    laps: float
    path: np.ndarray


# --------------------------------------------------------------------------------------------------- courses
def interior_point(course: Course) -> np.ndarray | None:
    """
    A point the course's loop goes around (inside its island), to count laps; ``None`` if there is none.

    For a corridor it is inside the centre line; for wall polylines, inside the first closed polyline that
    does not enclose the start (an island). Among grid points inside that polygon, the one furthest from it.
    """
    if course.corridor is not None:
        polygon = course.corridor.centerline
    else:
        start = np.array([course.start.x, course.start.y])
        islands = [p for p in _closed_polylines(course.walls) if not geometry.point_in_polygon(start, p)]
        if not islands:
            return None
        polygon = islands[0]
    x_min, y_min = polygon.min(axis=0)
    x_max, y_max = polygon.max(axis=0)
    grid = np.stack(np.meshgrid(np.linspace(x_min, x_max, 60), np.linspace(y_min, y_max, 60)), axis=-1).reshape(-1, 2)
    inside = np.array([geometry.point_in_polygon(point, polygon) for point in grid])
    if not inside.any():
        return None
    candidates = grid[inside]
    clearance = geometry.point_segment_distances(candidates, geometry.polyline_segments(polygon, closed=True)).min(axis=1)
    return np.asarray(candidates[int(np.argmax(clearance))])


def _closed_polylines(segments: np.ndarray) -> list[np.ndarray]:
    """Chains of consecutive segments whose end meets their start (the closed wall polylines)."""
    polylines, chain = [], [segments[0]]
    for segment in segments[1:]:
        if np.allclose(segment[:2], chain[-1][2:]):
            chain.append(segment)
        else:
            polylines.append(np.array(chain))
            chain = [segment]
    polylines.append(np.array(chain))
    return [np.vstack([c[:, :2], c[-1:, 2:]]) for c in polylines if np.allclose(c[0, :2], c[-1, 2:])]


def laps_driven(path: np.ndarray, centre: np.ndarray | None) -> float:
    """Signed number of turns of the path around ``centre`` (counter-clockwise positive); NaN without one."""
    if centre is None or len(path) < 2:
        return float("nan")
    angles = np.unwrap(np.arctan2(path[:, 1] - centre[1], path[:, 0] - centre[0]))
    return float((angles[-1] - angles[0]) / (2.0 * math.pi))


# -------------------------------------------------------------------------------------------------- evaluate
def run_episode(model: BaseAlgorithm, course: str, seed: int, jittered: bool, centre: np.ndarray | None) -> Episode:
    """One deterministic episode of the policy on a course (``MAX_STEPS`` steps at most)."""
    env = gym.make(ENV_ID, course=course, **(EVAL_JITTER if jittered else {}))
    obs, _ = env.reset(seed=seed)
    steps, collision = 0, False
    for steps in range(1, MAX_STEPS + 1):  # noqa: B007 (the last value is the episode length)
        action, _ = model.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            collision = bool(info["collision"])
            break
    path = cast(LidarObstacleCourseEnv, env.unwrapped).trajectory
    env.close()
    return Episode(course, seed, jittered, steps, collision, laps_driven(path, centre), path)


def evaluate(model: BaseAlgorithm, courses: list[str], n_episodes: int) -> list[Episode]:
    """The exact-start episode on the training course, then ``n_episodes`` jittered episodes per course."""
    centres = {course: interior_point(load_course(course)) for course in courses}
    episodes = [run_episode(model, TRAINING_COURSE, 0, False, centres[TRAINING_COURSE])]
    for course in courses:
        episodes.extend(run_episode(model, course, seed, True, centres[course]) for seed in range(n_episodes))
    return episodes


def summarise(episodes: list[Episode]) -> dict[str, Any]:
    """Per-course counts of collision-free jittered episodes, plus the exact-start episode."""
    exact = next(e for e in episodes if not e.jittered)
    per_course = {}
    for course in dict.fromkeys(e.course for e in episodes if e.jittered):
        runs = [e for e in episodes if e.jittered and e.course == course]
        per_course[course] = {
            "episodes": len(runs),
            "collision_free": sum(not e.collision for e in runs),
            "mean_steps": float(np.mean([e.steps for e in runs])),
            "mean_abs_laps": float(np.mean([abs(e.laps) for e in runs])),
        }
    return {
        "training_exact_start": {"steps": exact.steps, "collision": exact.collision, "laps": exact.laps},
        "courses": per_course,
    }


# ------------------------------------------------------------------------------------------------- training
class TrainingCourseEvaluation(BaseCallback):
    """
    Every ``freq`` steps: evaluate on the training course, append to ``learning_curve.csv`` and keep the best
    model (the engine saves the checkpoints, with the replay buffer, at the same timesteps).

    :param run_dir: Folder of the run
    :param freq: Steps between evaluations
    :param n_episodes: Jittered evaluation episodes
    """

    def __init__(self, run_dir: Path, freq: int, n_episodes: int):
        super().__init__()
        self.run_dir = run_dir
        self.freq = freq
        self.n_episodes = n_episodes
        self.state_path = run_dir / "state.json"
        self.state = json.loads(self.state_path.read_text()) if self.state_path.exists() else {"best": -1.0}
        self.centre = interior_point(load_course(TRAINING_COURSE))
        self._started = time.time()
        self._elapsed_before = float(self.state.get("elapsed_s", 0.0))

    def _on_step(self) -> bool:
        if self.num_timesteps % self.freq == 0:
            self.evaluate()
        return True

    def evaluate(self) -> None:
        """Evaluate, log and keep the best model."""
        runs = [run_episode(self.model, TRAINING_COURSE, seed, True, self.centre) for seed in range(self.n_episodes)]
        free = sum(not e.collision for e in runs)
        score = free + float(np.mean([e.steps for e in runs])) / MAX_STEPS  # collision-free first, then length
        row = {
            "timesteps": self.num_timesteps,
            "collision_free": free,
            "episodes": len(runs),
            "mean_steps": float(np.mean([e.steps for e in runs])),
            "wall_clock_s": round(self._elapsed_before + time.time() - self._started, 1),
        }
        self.state["elapsed_s"] = row["wall_clock_s"]
        curve = self.run_dir / "learning_curve.csv"
        new_file = not curve.exists()
        with curve.open("a", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=list(row))
            if new_file:
                writer.writeheader()
            writer.writerow(row)
        if score >= self.state["best"]:  # ties go to the later, longer-trained model
            self.state.update(best=score, best_timesteps=self.num_timesteps)
            with atomic_path(str(self.run_dir / "best_model.zip")) as temporary:
                self.model.save(temporary)
        text = json.dumps(self.state, indent=2)
        write_atomically(str(self.state_path), lambda stream: stream.write(text))


def train_model(args: argparse.Namespace, run_dir: Path) -> tuple[BaseAlgorithm, type[BaseAlgorithm]]:
    """
    Train, or resume, through the engine (:func:`sb3_adc.experiment.train` and :func:`~sb3_adc.experiment.resume`,
    in ``run_dir/run``): checkpoints with the replay buffer every ``--eval-freq`` steps; the engine's periodic
    evaluation is off, since the model is selected on the training course (:class:`TrainingCourseEvaluation`).
    Returns the final model and the algorithm class.
    """
    algorithm = load_hyperparams(args.algo, ENV_ID, conf_file=args.conf_file).algorithm_class
    callback = TrainingCourseEvaluation(run_dir, args.eval_freq, args.eval_episodes)
    engine_dir = run_dir / "run"
    if Path(RunLayout(str(engine_dir), ENV_ID).args).is_file():
        result = resume(str(engine_dir), n_timesteps=args.n_timesteps, callbacks=[callback])
    else:
        settings = TrainSettings(
            algo=args.algo,
            env_id=ENV_ID,
            seed=args.seed,
            conf_file=args.conf_file,
            n_timesteps=args.n_timesteps,
            log_folder=str(run_dir),
            run_dir=str(engine_dir),
            eval_freq=0,
            save_freq=args.eval_freq,
            keep_checkpoints=1,
            final_eval_episodes=1,
            device="cpu",
        )
        result = train(settings, callbacks=[callback])
    return algorithm.load(result.model_path, device="cpu"), algorithm


def plot_trajectories(episodes_by_model: dict[str, list[Episode]], title: str, path: Path) -> None:
    """
    One row per model, one panel per course: the course and every jittered episode's path (blue without a
    collision, red with a cross where it crashed).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_adc.experiment.plots import draw_course

    labels = list(episodes_by_model)
    courses = list(dict.fromkeys(e.course for e in episodes_by_model[labels[0]] if e.jittered))
    fig, axes = plt.subplots(len(labels), len(courses), figsize=(3.6 * len(courses), 3.3 * len(labels)), squeeze=False)
    for row, label in enumerate(labels):
        for ax, name in zip(axes[row], courses, strict=True):
            runs = [e for e in episodes_by_model[label] if e.jittered and e.course == name]
            for episode in runs:
                colour = "tab:red" if episode.collision else "tab:blue"
                ax.plot(episode.path[:, 0], episode.path[:, 1], color=colour, linewidth=0.6, alpha=0.6)
                if episode.collision:
                    ax.plot(*episode.path[-1], marker="x", color="tab:red", markersize=6)
            free = sum(not e.collision for e in runs)
            draw_course(ax, load_course(name), f"{label} model, {name}: {free}/{len(runs)}")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_learning_curves(results_dir: Path, path: Path) -> None:
    """
    Checkpoint evaluations on the training course (mean steps without a collision, out of 500), aggregated per
    configuration (a run folder ``<config>_seed<N>``): the mean over its seeds with a 95% stratified-bootstrap CI
    when it has several, each run as a thin line. Read from ``<results_dir>/*/learning_curve.csv``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    from sb3_adc.experiment.plots import display_name
    from sb3_adc.experiment.results import read_table
    from sb3_adc.experiment.statistics import learning_curves

    frames = []
    for curve_csv in sorted(results_dir.glob("*/learning_curve.csv")):
        config, _, seed = curve_csv.parent.name.rpartition("_seed")
        frame = read_table(curve_csv)
        frames.append(frame.assign(algo=config, env="training course", seed=int(seed), mean_return=frame["mean_steps"]))
    evaluations = pd.concat(frames, ignore_index=True)
    curves = learning_curves(evaluations, reps=2000, seed=0)

    def label(config: str) -> str:
        algo, _, variant = config.partition("_")
        return display_name(algo) + (", paper Table 2" if variant == "table2" else "")

    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    colors = plt.get_cmap("tab10")
    for index, (config, curve) in enumerate(curves.groupby("algo", sort=True)):
        color = colors(index % 10)
        runs = evaluations[evaluations["algo"] == config]
        for _, run in runs.groupby("seed"):
            ax.plot(run["timesteps"], run["mean_steps"], color=color, linewidth=0.6, alpha=0.35)
        n_runs = int(curve["n_runs"].iloc[0])
        ax.plot(
            curve["timesteps"],
            curve["mean"],
            color=color,
            marker="o",
            markersize=3,
            label=f"{label(str(config))} ({n_runs} run{'s' if n_runs > 1 else ''})",
        )
        if n_runs > 1:
            ax.fill_between(curve["timesteps"], curve["mean_ci_low"], curve["mean_ci_high"], color=color, alpha=0.2)
    ax.axhline(MAX_STEPS, color="0.5", linewidth=0.8, linestyle=":")
    ax.set_xlabel("training steps")
    ax.set_ylabel("mean steps without collision")
    ax.set_ylim(0, MAX_STEPS * 1.05)
    ax.set_title(
        "Checkpoint evaluations on the training course (10 jittered episodes each):\n"
        "mean over seeds with its 95% bootstrap CI; thin lines: each run",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_runs_table(results_dir: Path) -> None:
    """``runs.csv``: one row per run, model and course, gathered from every ``*/summary.json`` of the folder."""
    rows = []
    for summary_path in sorted(results_dir.glob("*/summary.json")):
        summary = json.loads(summary_path.read_text())
        for label, result in summary["results"].items():
            exact = result["training_exact_start"]
            base = {
                "run": summary_path.parent.name,
                "algo": summary["algo"],
                "hyperparams": summary["hyperparams"],
                "seed": summary["seed"],
                "n_timesteps": summary["n_timesteps"],
                "model": label,
                "model_timesteps": summary["best_model_timesteps"] if label == "best" else summary["n_timesteps"],
            }
            rows.append(
                {
                    **base,
                    "course": "training (exact start)",
                    "collision_free": int(not exact["collision"]),
                    "episodes": 1,
                    "mean_steps": exact["steps"],
                    "mean_abs_laps": round(abs(exact["laps"]), 3),
                }
            )
            for course, row in result["courses"].items():
                rows.append(
                    {
                        **base,
                        "course": course,
                        "collision_free": row["collision_free"],
                        "episodes": row["episodes"],
                        "mean_steps": round(row["mean_steps"], 1),
                        "mean_abs_laps": round(row["mean_abs_laps"], 3),
                    }
                )
    with (results_dir / "runs.csv").open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    # The same, compact: one line per run and model, "collision-free/episodes" per course (for the docs).
    compact: dict[tuple[str, str], dict[str, Any]] = {}
    for row in rows:
        line = compact.setdefault(
            (row["run"], row["model"]),
            {"run": row["run"], "model": f"{row['model']} ({row['model_timesteps']} steps)"},
        )
        line[row["course"]] = f"{row['collision_free']}/{row['episodes']}"
    with (results_dir / "transfer_table.csv").open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(next(iter(compact.values()))))
        writer.writeheader()
        writer.writerows(compact.values())


# ------------------------------------------------------------------------------------------------------ main
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", default="adc", choices=["adc", "ddpg", "td3"], help="algorithm (default adc)")
    parser.add_argument("--conf-file", default=None, help="hyperparameter file (default: the shipped hyperparams/<algo>.yml)")
    parser.add_argument("--n-timesteps", type=int, default=None, help="training steps (default: the entry's n_timesteps)")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--episodes", type=int, default=20, help="jittered evaluation episodes per course (default 20)")
    parser.add_argument("--eval-freq", type=int, default=2_500, help="steps between checkpoints/evaluations (default 2500)")
    parser.add_argument(
        "--eval-episodes", type=int, default=10, help="jittered episodes per checkpoint evaluation (default 10)"
    )
    parser.add_argument("--tag", default=None, help="name of the run (default: <algo>_seed<seed>)")
    parser.add_argument(
        "--run-dir", type=Path, default=ROOT / "logs" / "lidar_transfer", help="checkpoints (default logs/lidar_transfer)"
    )
    parser.add_argument("--tables-only", action="store_true", help="only rebuild runs.csv and transfer_table.csv in --out")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "lidar_transfer", help="results folder")
    args = parser.parse_args(argv)
    if args.tables_only:
        write_runs_table(args.out)
        plot_learning_curves(args.out, FIGURES_DIR / "lidar_learning_curves.png")
        print(f"Wrote {args.out / 'runs.csv'}, {args.out / 'transfer_table.csv'} and the learning curves' figure")
        return 0
    for name in ("episodes", "eval_freq", "eval_episodes"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")

    th.set_num_threads(1)
    tag = args.tag or f"{args.algo}_seed{args.seed}"
    run_dir = args.run_dir / tag
    run_dir.mkdir(parents=True, exist_ok=True)
    started = time.time()
    final_model, algorithm = train_model(args, run_dir)
    training_s = time.time() - started

    courses = [TRAINING_COURSE, *UNSEEN_COURSES]
    results: dict[str, Any] = {}
    all_episodes: list[dict[str, Any]] = []
    episodes_by_model: dict[str, list[Episode]] = {}
    for label, model in (("best", algorithm.load(run_dir / "best_model.zip", device="cpu")), ("final", final_model)):
        episodes = evaluate(model, courses, args.episodes)
        results[label] = summarise(episodes)
        all_episodes.extend(
            {
                "model": label,
                "course": e.course,
                "seed": e.seed,
                "jittered": e.jittered,
                "steps": e.steps,
                "collision": e.collision,
                "laps": round(e.laps, 3),
            }
            for e in episodes
        )
        episodes_by_model[label] = episodes

    state = json.loads((run_dir / "state.json").read_text())
    summary = {
        "script": "benchmarks/lidar_transfer.py",
        "algo": args.algo,
        "hyperparams": str(args.conf_file or f"hyperparams/{args.algo}.yml"),
        "seed": args.seed,
        "n_timesteps": final_model.num_timesteps,
        "best_model_timesteps": state.get("best_timesteps"),
        "training_wall_clock_s_this_run": round(training_s, 1),
        "evaluation": {"episodes_per_course": args.episodes, "start_jitter": EVAL_JITTER, "max_steps": MAX_STEPS},
        "sb3_adc": sb3_adc.__version__,
        "results": results,
    }
    out = args.out / tag
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    with (out / "episodes.csv").open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(all_episodes[0]))
        writer.writeheader()
        writer.writerows(all_episodes)
    (out / "learning_curve.csv").write_text((run_dir / "learning_curve.csv").read_text())
    shutil.copyfile(run_dir / "best_model.zip", out / "best_model.zip")  # small: the paper's network, ~0.3 MB

    print(f"\n{args.algo.upper()} on {ENV_ID}, {final_model.num_timesteps} steps, best model at {state.get('best_timesteps')}")
    print(f"{'course':<16} {'model':<6} {'collision-free':>14} {'mean steps':>10} {'mean |laps|':>11}")
    for label in ("best", "final"):
        exact = results[label]["training_exact_start"]
        print(
            f"{'training (exact)':<16} {label:<6} {'yes' if not exact['collision'] else 'no':>14} {exact['steps']:>10} "
            f"{abs(exact['laps']):>11.2f}"
        )
        for course, row in results[label]["courses"].items():
            print(
                f"{course:<16} {label:<6} {row['collision_free']:>9}/{row['episodes']:<4} {row['mean_steps']:>10.0f} "
                f"{row['mean_abs_laps']:>11.2f}"
            )
    figure_tag = "" if tag == "adc_seed0" else f"_{tag}"
    plot_trajectories(
        episodes_by_model,
        f"{args.algo.upper()} trained on 'training': best model ({state.get('best_timesteps')} steps) and final model "
        f"({final_model.num_timesteps} steps), collision-free episodes out of {args.episodes} (jittered starts)",
        FIGURES_DIR / f"lidar_transfer_trajectories{figure_tag}.png",
    )
    write_runs_table(args.out)
    plot_learning_curves(args.out, FIGURES_DIR / "lidar_learning_curves.png")
    print(f"Wrote {out}, {args.out / 'runs.csv'} and figures in {FIGURES_DIR}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
