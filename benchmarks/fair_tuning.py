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
``hyperparams/{algo}.yml`` (the files the evidence grid of ``benchmarks/critic_study.py --grid tuned`` trains on
fresh seeds) and ``summary.md``.

Usage::

    python benchmarks/fair_tuning.py --workers 2                # the study of every algorithm
    python benchmarks/fair_tuning.py --algos adc --workers 2    # one algorithm (the budget stays the same)
    python benchmarks/fair_tuning.py --quick                    # a smoke run
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import time
from pathlib import Path

import torch as th

from sb3_adc.experiment.provenance import machine_metadata
from sb3_adc.experiment.tuning import TuneSettings, tune

ROOT = Path(__file__).resolve().parent
RUNS_DIR = ROOT / "runs" / "fair_tuning"
RESULTS_DIR = ROOT / "results" / "fair_tuning"

ALGOS = ["adc", "ddpg", "td3", "sac"]
ENV_ID = "sb3_adc/NoisyPendulum-v1"
#: Tuning seeds: the evidence grid uses 1000-1009, which no trial sees.
SEEDS = (0, 1)
#: Algorithm -> the file of its starting entry. TD3 and SAC start from the RL Zoo's settings, which were their
#: shipped entries until the winners of this tuning replaced them; ADC and DDPG from their entries as shipped
#: when this tuning ran (``configs/warmup5000``; the warm-up ablation of ``critic_study.py`` changed them since).
STARTING_POINTS = {
    **{algo: str(ROOT / "configs" / "rl_zoo" / f"{algo}.yml") for algo in ("td3", "sac")},
    **{algo: str(ROOT / "configs" / "warmup5000" / f"{algo}.yml") for algo in ("adc", "ddpg")},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algos", nargs="+", choices=ALGOS, default=ALGOS)
    parser.add_argument("--n-trials", type=int, default=6, help="finished trials per algorithm, shipped entry included")
    parser.add_argument("-n", "--n-timesteps", type=int, default=20_000, help="budget of every run")
    parser.add_argument("--workers", type=int, default=1, help="worker processes per study")
    parser.add_argument("--quick", action="store_true", help="smoke run: 2 trials of 600 steps, results in *_quick")
    args = parser.parse_args()
    th.set_num_threads(1)
    name = "fair_tuning" + ("_quick" if args.quick else "")
    runs, output = RUNS_DIR.parent / name, RESULTS_DIR.parent / name
    n_trials, n_timesteps = (2, 600) if args.quick else (args.n_trials, args.n_timesteps)
    (output / "hyperparams").mkdir(parents=True, exist_ok=True)
    metadata_path = output / "metadata.json"
    metadata = json.loads(metadata_path.read_text()) if metadata_path.is_file() else {"wall_time_s": {}}
    rows = []
    for algo in args.algos:
        settings = TuneSettings(
            algo=algo,
            env_id=ENV_ID,
            conf_file=STARTING_POINTS.get(algo),
            n_trials=n_trials,
            n_timesteps=n_timesteps,
            seeds=SEEDS,
            sampler="tpe",
            pruner="median",
            n_startup_trials=3,
            n_evaluations=5,
            eval_episodes=5,
            final_eval_episodes=10,
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
        metadata["wall_time_s"][algo] = round(metadata["wall_time_s"].get(algo, 0.0) + elapsed, 1)
        (output / algo).mkdir(exist_ok=True)
        shutil.copyfile(Path(result.study_dir) / "trials.csv", output / algo / "trials.csv")
        shutil.copyfile(result.best_hyperparams_file, output / "hyperparams" / f"{algo}.yml")
        rows.append((algo, result))
    summary = ["| algorithm | finished trials | best trial | best mean final return (seeds 0, 1) |", "|---|---:|---|---:|"]
    for algo in ALGOS:
        trials_csv = output / algo / "trials.csv"
        if not trials_csv.is_file():
            continue
        with open(trials_csv, encoding="utf-8") as stream:
            trials = list(csv.DictReader(stream))
        finished = [row for row in trials if row["state"] in ("COMPLETE", "PRUNED")]
        complete = [row for row in trials if row["state"] == "COMPLETE"]
        best = max(complete, key=lambda row: float(row["value"]))
        label = "shipped entry" if best["shipped"] == "True" else f"trial {best['number']}"
        summary.append(f"| {algo} | {len(finished)} | {label} | {float(best['value']):.1f} |")
    (output / "summary.md").write_text("\n".join(summary) + "\n")
    metadata.update(
        {
            "env": ENV_ID,
            "seeds": list(SEEDS),
            "n_trials": n_trials,
            "n_timesteps": n_timesteps,
            "sampler": "tpe (3 random startup trials, seed 0 + worker)",
            "pruner": "median (3 startup trials, 5 evaluations of 5 episodes per run)",
            "objective": "mean over the seeds of the final evaluation (10 deterministic episodes)",
            "workers": args.workers,
            **machine_metadata(),
        }
    )
    metadata_path.write_text(json.dumps(metadata, indent=2) + "\n")
    print("\n".join(summary))


if __name__ == "__main__":
    main()
