"""
Fair tuning: ADC, DDPG, TD3 and SAC tuned with the same Optuna budget on the tuning seeds, by the one engine.

Each algorithm gets one study of ``sb3-adc train -optimize`` (:func:`sb3_adc.experiment.tuning.tune`) with the
same number of finished trials, the same seeds, budget, evaluation, sampler and pruner. The first trial of every
study is the algorithm's starting entry: for ADC and DDPG the one shipped when the tuning ran
(``benchmarks/configs/warmup5000/``), for TD3 and SAC the RL Zoo's Pendulum settings
(``benchmarks/configs/rl_zoo/``: what sb3-adc shipped for them before this tuning, whose winners it ships now),
so no tuned entry is worse than its starting point on the tuning seeds. ADC's space also covers its own knobs
(critic design, ``n_intervals``, Legendre degree), and ADC and DDPG share the critic-rate ratio and the
epsilon-gated exploration schedule (:mod:`sb3_adc.experiment.samplers`).

The studies go to ``benchmarks/runs/fair_tuning/`` (not committed; re-running the command resumes them). The
committed results in ``benchmarks/results/fair_tuning/``: each study's ``trials.csv``, the winners as
``hyperparams/{algo}.yml`` (the files the experiment ``benchmarks/experiments/noisy_pendulum_equal_tuning.yml`` trains on
fresh seeds) and ``summary.md``.

``--study lidar`` tunes the four ``sb3_adc/LidarObstacleCourse-v1`` entries the same way, for generalisation: a
trial's value is the success rate on the validation layouts (``VALIDATION_LAYOUT_SEEDS``, which neither training
nor the held-out test set uses), so the test layouts, the course files and the reporting seeds stay unseen. Every
algorithm gets the discount and clearance shaping that the budget sweeps found (``LIDAR_FIXED``, outside the
search), starts from its ``-v1`` starting entry (``configs/starting_entries/``, the entry shipped when the studies
began) with what the sweeps found (``configs/lidar_start/``: the buffer for all, for ADC also TD3's additions and a
lower actor rate), and searches its own space with the choices of
``LIDAR_SEARCH_SPACE``: the replay buffer for all, and for ADC, whose critic TD3's additions do not come with, the
twin critics, target smoothing and delayed actor updates (TD3 has them built in; DDPG's identity is to have none).
Its files go to ``benchmarks/runs/fair_tuning_lidar/`` and ``benchmarks/results/fair_tuning_lidar/``.

Usage::

    python benchmarks/fair_tuning.py --workers 2                # the study of every algorithm
    python benchmarks/fair_tuning.py --algos adc --workers 2    # one algorithm (the budget stays the same)
    python benchmarks/fair_tuning.py --study lidar --workers 16 # the lidar course (150,000 steps a run: many cores)
    python benchmarks/fair_tuning.py --quick                    # a smoke run
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch as th

from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc.experiment.tuning import TuneSettings, tune
from sb3_adc_envs.lidar_course.env import VALIDATION_LAYOUT_SEEDS

ROOT = Path(__file__).resolve().parent
RUNS_DIR = ROOT / "runs" / "fair_tuning"
RESULTS_DIR = ROOT / "results" / "fair_tuning"

ALGOS = ["adc", "ddpg", "td3", "sac"]
ENV_ID = "sb3_adc/NoisyPendulum-v1"
#: Tuning seeds: the evidence grid uses 1000-1009, which no trial sees.
SEEDS = (0, 1)
#: Algorithm -> the file of its starting entry. TD3 and SAC start from the RL Zoo's settings, which were their
#: shipped entries until the winners of this tuning replaced them; ADC and DDPG from their entries as shipped
#: when this tuning ran (``configs/warmup5000``; the warm-up ablation, ``experiments/warmup_ablation.yml``, changed
#: them since).
STARTING_POINTS = {
    **{algo: str(ROOT / "configs" / "rl_zoo" / f"{algo}.yml") for algo in ("td3", "sac")},
    **{algo: str(ROOT / "configs" / "warmup5000" / f"{algo}.yml") for algo in ("adc", "ddpg")},
}

LIDAR_ENV_ID = "sb3_adc/LidarObstacleCourse-v1"
#: Algorithm -> the starting entry of the lidar study (``configs/lidar_start``): the shipped ``-v1`` entry with what
#: the budget sweeps found for every learner (150,000 steps, the fixed settings below, a buffer that keeps the run),
#: and for ADC also its best updates there (TD3's additions, an actor learning rate of 3e-4).
LIDAR_STARTING_POINTS = {algo: str(ROOT / "configs" / "lidar_start" / f"{algo}.yml") for algo in ALGOS}
#: Fixed for every algorithm of the lidar study: the discount and the potential-based clearance shaping (at the
#: same discount) that raised both ADC and TD3 in the budget sweeps (docs/results/critic_designs.rst).
LIDAR_FIXED: dict[str, Any] = {
    "gamma": 0.98,
    "env_wrapper": [{"sb3_adc_envs.wrappers.ClearanceShaping": {"gamma": 0.98}}],
}
#: Choices searched beside each algorithm's own space in the lidar study. ADC's critic designs are its sampler's
#: (``legendre``, ``state_value``, ``paper``): the ``action_network`` design, worse than ``legendre`` at 150,000 steps
#: in the critic-design sweep, evaluates its advantage network at every interval centre of every sample and made a
#: trial of batches of 256 about ten times slower than the starting entry's (two such trials of a first attempt of
#: this study would have taken over two hours each on this course).
LIDAR_SEARCH_SPACE: dict[str, dict[str, list[Any]]] = {algo: {"buffer_size": [50_000, 200_000]} for algo in ALGOS}
LIDAR_SEARCH_SPACE["adc"].update(
    {
        "policy_delay": [1, 2],
        "target_policy_noise": [0.0, 0.2],
        "policy_kwargs": [
            "dict(net_arch=dict(pi=[100, 20], qf=[100]), value_net_arch=[20], n_critics=1)",
            "dict(net_arch=dict(pi=[100, 20], qf=[100]), value_net_arch=[20], n_critics=2)",
        ],
    }
)


@dataclass(frozen=True)
class Study:
    """One study per algorithm with these settings (see the module's docstring)."""

    env_id: str
    n_trials: int
    n_timesteps: int
    objective: str
    final_eval_episodes: int
    eval_episodes: int
    starting_points: dict[str, str]
    fixed: dict[str, Any]
    search_space: dict[str, dict[str, list[Any]]]
    eval_env_kwargs: dict[str, Any]


STUDIES = {
    "pendulum": Study(ENV_ID, 6, 20_000, "return", 10, 5, STARTING_POINTS, {}, {}, {}),
    "lidar": Study(
        LIDAR_ENV_ID,
        8,
        150_000,
        "success",
        50,
        20,
        LIDAR_STARTING_POINTS,
        LIDAR_FIXED,
        LIDAR_SEARCH_SPACE,
        {"layout_seeds": list(VALIDATION_LAYOUT_SEEDS)},
    ),
}


def starting_point(study: Study, algo: str) -> str:
    """The starting entry of ``algo`` in ``study``, as the metadata names it: a file of the repository or the shipped one."""
    path = study.starting_points.get(algo)
    return str(Path(path).relative_to(ROOT.parent)) if path else f"hyperparams/{algo}.yml (shipped)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--study", choices=list(STUDIES), default="pendulum", help="which tuning (default: pendulum)")
    parser.add_argument("--algos", nargs="+", choices=ALGOS, default=ALGOS)
    parser.add_argument("--n-trials", type=int, default=None, help="finished trials per algorithm (default: the study's)")
    parser.add_argument("-n", "--n-timesteps", type=int, default=None, help="budget of every run (default: the study's)")
    parser.add_argument("--workers", type=int, default=1, help="worker processes per study")
    parser.add_argument("--quick", action="store_true", help="smoke run: 2 trials of 600 steps, results in *_quick")
    args = parser.parse_args()
    th.set_num_threads(1)
    study = STUDIES[args.study]
    name = "fair_tuning" + ("" if args.study == "pendulum" else f"_{args.study}") + ("_quick" if args.quick else "")
    runs, output = RUNS_DIR.parent / name, RESULTS_DIR.parent / name
    n_trials = 2 if args.quick else args.n_trials or study.n_trials
    n_timesteps = 600 if args.quick else args.n_timesteps or study.n_timesteps
    (output / "hyperparams").mkdir(parents=True, exist_ok=True)
    metadata_path = output / "metadata.json"
    metadata = json.loads(metadata_path.read_text()) if metadata_path.is_file() else {"wall_time_s": {}}
    for algo in args.algos:
        settings = TuneSettings(
            algo=algo,
            env_id=study.env_id,
            conf_file=study.starting_points.get(algo),
            n_trials=n_trials,
            n_timesteps=n_timesteps,
            seeds=SEEDS,
            sampler="tpe",
            pruner="median",
            n_startup_trials=3,
            n_evaluations=5,
            eval_episodes=study.eval_episodes,
            final_eval_episodes=study.final_eval_episodes,
            objective=study.objective,
            overrides=dict(study.fixed),
            search_space=study.search_space.get(algo, {}),
            eval_env_kwargs=dict(study.eval_env_kwargs),
            n_jobs=args.workers,
            log_folder=str(runs),
            sampler_seed=0,
            device="cpu",
        )
        start = time.perf_counter()
        result = tune(settings)
        elapsed = time.perf_counter() - start
        if result.n_finished > n_trials:
            raise SystemExit(f"the {algo} study holds {result.n_finished} trials, more than the budget {n_trials}")
        # An invocation that only reports (its study finished before) adds no wall time and keeps the workers and
        # machine of the invocations that trained.
        trained = result.n_finished > len(finished(read_trials(output / algo / "trials.csv")))
        if trained:
            metadata["wall_time_s"][algo] = round(metadata["wall_time_s"].get(algo, 0.0) + elapsed, 1)
        invocation = {"workers": args.workers, **machine_metadata()} if trained or "workers" not in metadata else {}
        (output / algo).mkdir(exist_ok=True)
        shutil.copyfile(Path(result.study_dir) / "trials.csv", output / algo / "trials.csv")
        shutil.copyfile(result.best_hyperparams_file, output / "hyperparams" / f"{algo}.yml")
        # Written after every algorithm, so that a long invocation stopped later keeps what it finished.
        summary, trial_time = summarise(output, study)
        metadata.update(
            {
                "env": study.env_id,
                "seeds": list(SEEDS),
                "n_trials": n_trials,
                "n_timesteps": n_timesteps,
                "sampler": "tpe (3 random startup trials, seed 0 + worker)",
                "pruner": f"median (3 startup trials, 5 evaluations of {study.eval_episodes} episodes per run)",
                "objective": f"mean over the seeds of the final evaluation's {study.objective} "
                f"({study.final_eval_episodes} deterministic episodes)",
                "fixed": study.fixed,
                # Per algorithm, merged with those of earlier invocations (``--algos`` tunes some algorithms at a time).
                "starting_points": metadata.get("starting_points", {}) | {algo: starting_point(study, algo)},
                "search_space": metadata.get("search_space", {}) | {algo: study.search_space.get(algo, {})},
                "trial_time_s": trial_time,
                "eval_env_kwargs": study.eval_env_kwargs,
                **invocation,
            }
        )
        metadata_path.write_text(json.dumps(metadata, indent=2) + "\n")
        print("\n".join(summary))


def read_trials(trials_csv: Path) -> list[dict[str, str]]:
    """The rows of a study's ``trials.csv`` in the results (none without one)."""
    if not trials_csv.is_file():
        return []
    with open(trials_csv, encoding="utf-8") as stream:
        return list(csv.DictReader(stream))


def finished(trials: list[dict[str, str]]) -> list[dict[str, str]]:
    """The trials that count towards the budget: complete or pruned."""
    return [row for row in trials if row["state"] in ("COMPLETE", "PRUNED")]


def summarise(output: Path, study: Study) -> tuple[list[str], dict[str, float]]:
    """
    Write ``summary.md`` for every algorithm with a ``trials.csv`` in ``output``; return its lines and, per
    algorithm, the summed duration of its finished trials in seconds (the study's compute, whatever the
    invocations and interruptions).
    """
    quantity = "return" if study.objective == "return" else "success rate on validation layouts"
    summary = [
        f"| algorithm | finished trials | best trial | best mean final {quantity} (seeds 0, 1) |",
        "|---|---:|---|---:|",
    ]
    trial_time = {}
    for algo in ALGOS:
        trials = read_trials(output / algo / "trials.csv")
        if not trials:
            continue
        done = finished(trials)
        complete = [row for row in trials if row["state"] == "COMPLETE"]
        best = max(complete, key=lambda row: float(row["value"]))
        label = "starting entry" if best["shipped"] == "True" else f"trial {best['number']}"
        value = f"{float(best['value']):.1f}" if study.objective == "return" else f"{float(best['value']):.2f}"
        summary.append(f"| {algo} | {len(done)} | {label} | {value} |")
        trial_time[algo] = round(sum(float(row["duration_s"] or 0.0) for row in done), 1)
    (output / "summary.md").write_text("\n".join(summary) + "\n")
    return summary, trial_time


if __name__ == "__main__":
    main()
