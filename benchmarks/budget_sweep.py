"""
Does ADC reach the >= 90% success target on unseen procedural layouts with a larger training budget or a longer
horizon? The ``sb3_adc/LidarObstacleCourse-v1`` entry as first shipped trains for 30,000 steps with gamma 0.9 and
reaches a held-out success IQM of 0.18 (``procedural_generalisation.py``). This sweep trains ADC with that entry
(the configuration named ``shipped``) and with each ``--gammas`` value for ``--n-timesteps`` (default 100,000) and
keeps a checkpoint every tenth of the budget; each checkpoint is a model trained for that many steps (nothing in
the entry depends on the total budget: constant learning rates, an exploration schedule in steps), so one run gives
the whole budget curve.

Every checkpoint is scored, deterministically, on the validation layouts (``VALIDATION_LAYOUT_SEEDS``,
2,000,000-2,000,099, ``--layouts`` of them): a split that neither training (0-999,999) nor the held-out test set
(1,000,000-1,000,099) uses, so the choices made from this sweep leave the test layouts and course files unseen.
The runs use tuning seeds (default 0-2), never the reporting seeds 1000-1009. A configuration whose model deploys
an averaged actor (``actor_average_tau`` of ADC, TD3 or DDPG) is also scored with the actor itself, as
``"{name} (actor itself)"``: both policies of the same runs.

Training is ``sb3-adc benchmark``'s engine (resumable, one process per run); the runs go to
``benchmarks/runs/budget_sweep/`` (not committed), the table to ``benchmarks/results/budget_sweep/{name}/``
(``sweep.csv``: one row per run and checkpoint; ``curves.csv``: mean and IQM across runs with 95% CIs;
``summary.md``), the figure to ``docs/_static/benchmarks/budget_sweep_{name}.png``.

``--configs FILE`` replaces that entry and ``--gammas`` with the configurations of a YAML file (a mapping of
configuration name to ``key: value`` overrides of the entry, checked as the engine checks ``-params``); its results
go to a folder named after the file (``{env}_{algo}_{file stem}``), and the sweep ends by naming the configuration
that the rule of pre-registered sweeps chooses (``winner``: the highest mean success at the last checkpoint).

Every configuration overrides the algorithm's starting entry, the ``-v1`` entry as shipped when the studies began,
frozen in ``benchmarks/configs/starting_entries/`` (``STARTING_ENTRIES`` of ``procedural_generalisation.py``): a
sweep keeps meaning what it meant when it ran whatever the shipped entries become.

Usage::

    python benchmarks/budget_sweep.py --workers 2
    python benchmarks/budget_sweep.py --configs benchmarks/configs/budget_sweep/wide.yml --workers 2
    python benchmarks/budget_sweep.py --quick      # a smoke run
    python benchmarks/budget_sweep.py --replot     # redraw the figure from the committed sweep.csv
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from fractions import Fraction
from functools import partial
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd
import torch as th
from procedural_generalisation import (
    STARTING_ENTRIES,
    drop_actor_average,
    layout_success,
    load_for_scoring,
    read_configs,
    report,
    repository_path,
    training_record,
)

from sb3_adc.config.loader import HyperparamsError
from sb3_adc.experiment.benchmark import BenchmarkSettings, RunSpec, run_benchmarks, run_script
from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.plots import plot_learning_curves
from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc.experiment.results import read_table
from sb3_adc.experiment.statistics import learning_curves
from sb3_adc_envs.lidar_course.env import VALIDATION_LAYOUT_SEEDS

ROOT = Path(__file__).resolve().parent
RUNS_DIR = ROOT / "runs" / "budget_sweep"
RESULTS_DIR = ROOT / "results" / "budget_sweep"
DOCS_STATIC = ROOT.parent / "docs" / "_static" / "benchmarks"

TUNING_SEEDS = [0, 1, 2]
#: Checkpoints per run (every tenth of the budget).
N_CHECKPOINTS = 10
SHIPPED = "shipped"
TARGET = 0.9


def config_name(gamma: float | None) -> str:
    return SHIPPED if gamma is None else f"gamma {gamma:g}"


def score_checkpoint(
    run_dir: str, config: str, seed: int, timesteps: int, model_path: str, n_layouts: int
) -> list[dict[str, Any]]:
    """
    The success rate of one checkpoint on the first ``n_layouts`` validation layouts, one episode each. A model that
    deploys an averaged actor (``actor_average_tau`` of ADC, TD3 or DDPG) is scored twice: as deployed, and with the
    actor itself as configuration ``"{config} (actor itself)"``, the same run's two policies.
    """
    th.set_num_threads(1)
    settings, entry, model, kwargs = load_for_scoring(run_dir, path=model_path)
    env = entry.wrap_env(gym.make(settings.env_id, **{**kwargs, "layout_seeds": VALIDATION_LAYOUT_SEEDS}))
    first = VALIDATION_LAYOUT_SEEDS[0]

    def row(name: str) -> dict[str, Any]:
        successes = [layout_success(model, env, first + k) for k in range(n_layouts)]
        return {
            "config": name,
            "algo": settings.algo,
            "env": settings.env_id,
            "seed": seed,
            "timesteps": timesteps,
            "episodes": n_layouts,
            "successes": int(sum(successes)),
            "success_rate": float(np.mean(successes)),
        }

    rows = [row(config)]
    if drop_actor_average(model):
        rows.append(row(f"{config} (actor itself)"))
    env.close()
    return rows


def checkpoint_line(rows: list[dict[str, Any]]) -> str:
    """Progress: one scored checkpoint, its run and its success rate (and its actor's, when it deploys an average)."""
    first = rows[0]
    rates = ", ".join(f"{row['config']} {row['success_rate']:.2f}" for row in rows)
    return f"seed {first['seed']} at {first['timesteps']} steps: {rates}"


def winner(sweep: pd.DataFrame, configs: Mapping[str, Mapping[str, Any]]) -> str:
    """
    The configuration a pre-registered sweep chooses (the rule written down before DDPG's and SAC's sweeps ran,
    ``docs/results/critic_designs.rst``): the highest mean validation success across runs at the last checkpoint, of
    each configuration as deployed (an averaged actor, not its ``"(actor itself)"`` rows); on a tie, the one with the
    longer returns (``n_steps``, 1 when unnamed). Success is compared as counts over equal episodes, so a tie is exact.

    :param sweep: The sweep's ``sweep.csv``
    :param configs: The sweep's configurations (name -> overrides), those of its ``--configs`` file
    """
    final = sweep[(sweep["timesteps"] == sweep["timesteps"].max()) & sweep["config"].isin(list(configs))]
    totals = final.groupby("config")[["successes", "episodes"]].sum()
    if set(totals.index) != set(configs):
        raise ValueError(f"the sweep has no final checkpoint of {sorted(set(configs) - set(totals.index))}")
    return max(
        configs,
        key=lambda name: (
            Fraction(int(totals.loc[name, "successes"]), int(totals.loc[name, "episodes"])),
            int(configs[name].get("n_steps", 1)),
        ),
    )


def summarise(sweep: pd.DataFrame, reps: int) -> pd.DataFrame:
    """Mean and IQM success rate across runs at each checkpoint, per configuration, with 95% CIs."""
    panel = f"validation layouts (target {TARGET:.0%})"
    table = sweep.rename(columns={"success_rate": "mean_return"}).assign(env=panel, algo=sweep["config"])
    return learning_curves(table, reps=reps).rename(columns={"algo": "config"})


def plot(curves: pd.DataFrame, path: Path, env_id: str, algo: str) -> None:
    frame = curves.rename(columns={"config": "algo"})
    title = f"{algo.upper()} on {env_id}: mean of runs, 95% CI"
    plot_learning_curves(frame, str(path), title=title, ylabel="success rate (share of collision-free episodes)")


def markdown(curves: pd.DataFrame) -> str:
    lines = [
        "| configuration | timesteps | runs | success rate mean [95% CI] | IQM |",
        "|---|---:|---:|---|---:|",
    ]
    for row in curves.sort_values(["config", "timesteps"]).itertuples(index=False):
        lines.append(
            f"| {row.config} | {row.timesteps} | {row.n_runs} | {row.mean:.2f} [{row.mean_ci_low:.2f}, "
            f"{row.mean_ci_high:.2f}] | {row.iqm:.2f} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="sb3_adc/LidarObstacleCourse-v1", help="the procedural environment id")
    parser.add_argument("--algo", default="adc", choices=["adc", "ddpg", "td3", "sac"])
    parser.add_argument("--gammas", type=float, nargs="*", default=[0.98], help="discounts tried beside the entry's")
    parser.add_argument("--configs", help="YAML file of configurations (name -> overrides) instead of the entry and --gammas")
    parser.add_argument("--seeds", type=int, nargs="+", default=TUNING_SEEDS, help="tuning seeds (0-4)")
    parser.add_argument("-n", "--n-timesteps", type=int, default=100_000, help="budget of every run")
    parser.add_argument("--layouts", type=int, default=50, help="validation layouts per checkpoint")
    parser.add_argument("--workers", type=int, default=1, help="parallel runs and scorings")
    parser.add_argument("--reps", type=int, default=5000, help="bootstrap replications")
    parser.add_argument("--quick", action="store_true", help="smoke run: 1 seed, 1,000 steps, 3 layouts")
    parser.add_argument("--replot", action="store_true", help="redraw the figure from the committed sweep.csv")
    args = parser.parse_args()
    if not set(args.seeds) <= set(range(5)):
        parser.error(f"--seeds must be tuning seeds in 0-4 (the reporting seeds 1000+ stay unseen), got {args.seeds}")
    if not all(0.0 < gamma < 1.0 for gamma in args.gammas):
        parser.error(f"--gammas must be in (0, 1), got {args.gammas}")
    span = VALIDATION_LAYOUT_SEEDS[1] - VALIDATION_LAYOUT_SEEDS[0]
    if not 1 <= args.layouts <= span:
        parser.error(f"--layouts must be in [1, {span}], got {args.layouts}")
    if min(args.workers, args.reps, args.n_timesteps // N_CHECKPOINTS) < 1:
        parser.error(f"--workers and --reps must be >= 1, --n-timesteps >= {N_CHECKPOINTS}")
    th.set_num_threads(1)
    seeds, n_timesteps, n_layouts, reps = args.seeds, args.n_timesteps, args.layouts, args.reps
    if args.quick:
        seeds, n_timesteps, n_layouts, reps = seeds[:1], 1000, 3, 200
    try:
        file_configs = read_configs(args.configs) if args.configs else None
    except (OSError, HyperparamsError) as error:
        parser.error(f"--configs: {error}")
    stem = f"_{Path(args.configs).stem}" if args.configs else ""
    name = f"{args.env.split('/')[-1]}_{args.algo}{stem}" + ("_quick" if args.quick else "")
    output = RESULTS_DIR / name
    figure = DOCS_STATIC / f"budget_sweep_{name}.png"
    if args.replot:
        plot(summarise(read_table(output / "sweep.csv"), reps), figure, args.env, args.algo)
        print(f"wrote {figure}")
        return
    output.mkdir(parents=True, exist_ok=True)
    configs: dict[str, dict[str, Any]] = file_configs or {config_name(None): {}} | {
        config_name(gamma): {"gamma": gamma} for gamma in args.gammas
    }
    start = time.perf_counter()
    grids = {
        config: BenchmarkSettings(
            algos=[args.algo],
            env_ids=[args.env],
            seeds=seeds,
            log_folder=str(RUNS_DIR / name / config.replace(" ", "_")),
            n_timesteps=n_timesteps,
            overrides=overrides,
            conf_folder=str(STARTING_ENTRIES),
            eval_freq=n_timesteps // N_CHECKPOINTS,
            eval_episodes=5,
            final_eval_episodes=20,
            device="cpu",
            keep_checkpoints=N_CHECKPOINTS + 1,
        )
        for config, overrides in configs.items()
    }
    # One grid per configuration (a grid has one set of overrides), all in one pool of workers.
    results = run_benchmarks(list(grids.values()), workers=args.workers, report=partial(report, by_folder=True))
    statuses = Counter(outcome.status for result in results for outcome in result.outcomes)
    jobs = []
    for (config, settings), result in zip(grids.items(), results, strict=True):
        if result.failures:
            raise SystemExit(f"{len(result.failures)} runs of {config} failed; re-run to retry them")
        for seed in seeds:
            run_dir = RunSpec(args.algo, args.env, seed).run_dir(settings.log_folder)
            checkpoints = RunLayout(run_dir, args.env).checkpoints()
            if len(checkpoints) < N_CHECKPOINTS:
                raise SystemExit(f"{run_dir}: {len(checkpoints)} checkpoints, expected {N_CHECKPOINTS}")
            jobs += [(run_dir, config, seed, point.timesteps, point.model, n_layouts) for point in checkpoints]
    training = training_record(output, statuses, time.perf_counter() - start, args.workers, runs_folder=RUNS_DIR / name)
    start = time.perf_counter()
    scored: list[dict[str, Any]] = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for done, rows in enumerate(pool.map(score_checkpoint, *zip(*jobs, strict=True)), 1):
            print(f"scored [{done}/{len(jobs)}] {checkpoint_line(rows)}", flush=True)
            scored += rows
    sweep = pd.DataFrame(scored)
    scoring_s = round(time.perf_counter() - start, 1)
    sweep.to_csv(output / "sweep.csv", index=False)
    curves = summarise(sweep, reps)
    curves.to_csv(output / "curves.csv", index=False)
    (output / "summary.md").write_text(markdown(curves))
    if not args.quick:
        DOCS_STATIC.mkdir(parents=True, exist_ok=True)
        plot(curves, figure, args.env, args.algo)
    best = curves.loc[curves["mean"].idxmax()]
    metadata = {
        "env": args.env,
        "algo": args.algo,
        "configs": configs,
        "configs_file": repository_path(args.configs) if args.configs else None,
        "hyperparams": f"starting entries ({repository_path(str(STARTING_ENTRIES))}/{{algo}}.yml) with each config's "
        "overrides",
        "seeds": seeds,
        "n_timesteps": n_timesteps,
        "checkpoint_every": n_timesteps // N_CHECKPOINTS,
        "validation_layouts": [VALIDATION_LAYOUT_SEEDS[0], VALIDATION_LAYOUT_SEEDS[0] + n_layouts - 1],
        "target_success": TARGET,
        "best": {"config": best["config"], "timesteps": int(best["timesteps"]), "mean": round(float(best["mean"]), 3)},
        "runs_this_invocation": dict(sorted(statuses.items())),
        **training,
        "scoring_wall_time_s": scoring_s,
        "workers": args.workers,
        "bootstrap_reps": reps,
        **machine_metadata(),
    }
    (output / "metadata.json").write_text(json.dumps(metadata, indent=2) + "\n")
    print(markdown(curves))
    if file_configs:
        print(f"chosen by the sweep's rule (budget_sweep.winner): {winner(sweep, configs)}")


if __name__ == "__main__":
    run_script(main)
