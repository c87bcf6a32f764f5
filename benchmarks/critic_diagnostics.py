"""
Critic diagnostics of ADC's designs, DDPG and TD3 on the noisy Pendulum: what the critic study's numbers come from.

Each configuration of the critic-design screen and of the fresh-seed comparison (their experiment files,
``benchmarks/experiments/critic_design_screen.yml`` and ``noisy_pendulum_paper_critic.yml``) trains on the
benchmark engine with :class:`~sb3_adc.diagnostics.CriticDiagnosticsCallback` added through its hyperparameter
entry (``callback:``). The diagnostics select nothing, so they run on the tuning seeds or on the fresh seeds
alike. The callback logs the critic's bias against discounted Monte-Carlo returns of deterministic evaluation
rollouts, the actor-gradient and ``dQ/da`` norms and, for ADC, the visits of each action interval and the
roughness of the advantage across neighbouring intervals.

The runs go to ``benchmarks/runs/critic_diagnostics{_tag}/`` (not committed); a table of the last record of each
run to ``benchmarks/results/critic_diagnostics{_tag}/``, the histories of the runs next to it, the IQM of the last
records with 95% stratified-bootstrap CIs over runs (``summary_ci.csv``), and the figure to
``docs/_static/benchmarks/critic_diagnostics{_tag}.png``.

Usage::

    python benchmarks/critic_diagnostics.py --workers 2
    python benchmarks/critic_diagnostics.py --configs adc_paper adc_legendre ddpg \
        --seeds 1000 1001 1002 1003 1004 1005 1006 1007 1008 1009 --tag fresh --workers 2
    python benchmarks/critic_diagnostics.py --quick
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
import torch as th

from sb3_adc.diagnostics import ARRAY_KEYS, load_history, plot_diagnostics
from sb3_adc.experiment.benchmark import BenchmarkSettings, RunOutcome, run_benchmark, run_script
from sb3_adc.experiment.experiments import read_experiment
from sb3_adc.experiment.statistics import final_performance

ROOT = Path(__file__).resolve().parent
RUNS_DIR = ROOT / "runs" / "critic_diagnostics"
RESULTS_DIR = ROOT / "results" / "critic_diagnostics"
DOCS_STATIC = ROOT.parent / "docs" / "_static" / "benchmarks"
ENV_ID = "sb3_adc/NoisyPendulum-v1"
DEFAULT_CONFIGS = ["adc_paper", "adc_legendre", "ddpg", "td3"]
#: The last records summarised with CIs over runs: the critic's bias, and the ADC-only advantage roughness.
CI_KEYS = ["eval/critic_bias", "eval/critic_bias_abs", "train/advantage_roughness"]
#: The configurations of the critic-design screen and of the fresh-seed comparison, by name.
CONFIGS = {
    name: config
    for stem in ("critic_design_screen", "noisy_pendulum_paper_critic")
    for name, config in read_experiment(str(ROOT / "experiments" / f"{stem}.yml")).configs.items()
}


def report(outcome: RunOutcome, done: int, total: int) -> None:
    final = "" if outcome.final is None else f" final return {outcome.final['mean_return']:.1f}"
    print(f"[{done}/{total}] {outcome.spec}: {outcome.status}{final}", flush=True)
    if outcome.status == "failed":
        print(outcome.error, flush=True)


def summary_with_cis(table: pd.DataFrame, reps: int) -> pd.DataFrame:
    """IQM and mean of each of :data:`CI_KEYS` per configuration, with 95% stratified-bootstrap CIs over runs."""
    frames = []
    for key in (key for key in CI_KEYS if key in table.columns):  # ADC's metrics are absent from DDPG-only tables
        runs = table[["config", "seed", key]].dropna()
        if not runs.empty:
            scores = runs.rename(columns={"config": "algo", key: "mean_return"}).assign(env=key)
            frames.append(final_performance(scores, reps=reps).rename(columns={"env": "metric", "algo": "config"}))
    return pd.concat(frames, ignore_index=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--configs", nargs="+", choices=sorted(CONFIGS), default=DEFAULT_CONFIGS)
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1], help="seeds (default: tuning seeds 0 and 1)")
    parser.add_argument("-n", "--n-timesteps", type=int, default=20_000, help="budget of every run")
    parser.add_argument("--workers", type=int, default=1, help="parallel runs")
    parser.add_argument("--tag", default="", help="suffix of the runs, results and figure names (e.g. fresh)")
    parser.add_argument("--reps", type=int, default=5000, help="bootstrap replications of summary_ci.csv")
    parser.add_argument("--quick", action="store_true", help="smoke run: 1 seed, 1500 steps, results in *_quick")
    args = parser.parse_args()
    if args.workers < 1 or args.reps < 1 or (args.tag and not args.tag.replace("_", "").isalnum()):
        parser.error("--workers and --reps must be >= 1, --tag letters, digits and underscores")
    th.set_num_threads(1)
    suffix = (f"_{args.tag}" if args.tag else "") + ("_quick" if args.quick else "")
    seeds = args.seeds[:1] if args.quick else args.seeds
    n_timesteps = 1500 if args.quick else args.n_timesteps
    every = max(n_timesteps // 10, 1)
    output = RESULTS_DIR.with_name(RESULTS_DIR.name + suffix)
    start = time.perf_counter()
    histories: dict[str, list[list[dict]]] = {}
    rows = []
    for name in args.configs:
        algo, overrides, conf_folder = CONFIGS[name].algo, CONFIGS[name].overrides, CONFIGS[name].hyperparams
        folder = RUNS_DIR.with_name(RUNS_DIR.name + suffix) / name

        def run_seed(
            seed: int,
            algo: str = algo,
            overrides: dict = overrides,
            conf_folder: str | None = conf_folder,
            folder: Path = folder,
        ) -> Path:
            # One grid per seed, in its own folder: each run writes its diagnostics to its own history folder, and
            # grids of several seeds run at once (one process each) without sharing tables.
            history_dir = folder / f"diagnostics_seed{seed}"
            callback = {
                "sb3_adc.diagnostics.CriticDiagnosticsCallback": {
                    "eval_env": ENV_ID,
                    "eval_freq": every,
                    "log_freq": every,
                    "n_eval_episodes": 5,
                    "save_path": str(history_dir),
                }
            }
            settings = BenchmarkSettings(
                algos=[algo],
                env_ids=[ENV_ID],
                seeds=[seed],
                log_folder=str(folder / f"seed{seed}"),
                n_timesteps=n_timesteps,
                overrides={**overrides, "callback": callback},
                conf_folder=conf_folder,
                device="cpu",
            )
            result = run_benchmark(settings, workers=1, report=report)
            if result.failures:
                raise SystemExit(f"{algo}, seed {seed} failed; re-run to retry it")
            return history_dir

        with ThreadPoolExecutor(max_workers=args.workers) as pool:
            history_dirs = list(pool.map(run_seed, seeds))
        runs = []
        for seed, history_dir in zip(seeds, history_dirs, strict=True):
            history = load_history(str(history_dir))
            runs.append(history)
            output.mkdir(parents=True, exist_ok=True)
            shutil.copy(history_dir / "critic_diagnostics.csv", output / f"{name}_seed{seed}.csv")
            last = {key: value for record in history for key, value in record.items() if key not in ARRAY_KEYS}
            rows.append({"config": name, "seed": seed, **last})
        histories[name] = runs
    table = pd.DataFrame(rows)
    table.to_csv(output / "last_records.csv", index=False)
    summary = table.drop(columns=["seed"]).groupby("config", sort=False).mean(numeric_only=True)
    summary.to_csv(output / "summary.csv")
    summary_with_cis(table, 200 if args.quick else args.reps).to_csv(output / "summary_ci.csv", index=False)
    figure = DOCS_STATIC / f"critic_diagnostics{suffix}.png"
    figure.parent.mkdir(parents=True, exist_ok=True)
    plot_diagnostics(histories, str(figure), title=f"Critic diagnostics on {ENV_ID} (seeds {seeds})")
    wall_time = time.perf_counter() - start
    metadata = {
        "configs": list(args.configs),
        "seeds": seeds,
        "n_timesteps": n_timesteps,
        "workers": args.workers,
        "wall_time_s": round(wall_time, 1),
        "note": "wall time of this invocation (runs finished by an earlier one are skipped)",
    }
    (output / "metadata.json").write_text(json.dumps(metadata, indent=2) + "\n")
    print(f"wall time {wall_time:.0f} s")
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(summary.replace({np.nan: None}))


if __name__ == "__main__":
    run_script(main)
