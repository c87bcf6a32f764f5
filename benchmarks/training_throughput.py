"""
Training throughput of ADC against SB3's DDPG, measured in the same run.

Throughput is environment steps per second of ``learn()`` past the warm-up, one gradient step per environment
step (``train_freq=1``), so it includes rollout collection, replay sampling and every update. Both algorithms
get identical layer sizes: the DDPG critic's hidden layers are ADC's shared trunk, on top of which ADC adds its
value output and its ``n_intervals`` advantage outputs. Runs alternate between the algorithms so that drift of
the machine's speed affects both alike; the median over repeats is reported.

Usage::

    python benchmarks/training_throughput.py            # full run, writes benchmarks/results/
    python benchmarks/training_throughput.py --quick    # a smoke run
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import stable_baselines3
import torch as th
from stable_baselines3 import DDPG
from stable_baselines3.common.base_class import BaseAlgorithm

import sb3_adc
from sb3_adc import ADC

RESULTS_DIR = Path(__file__).parent / "results"


@dataclass(frozen=True)
class Setting:
    """One network size at which both algorithms are timed."""

    name: str
    net_arch: list[int]
    batch_size: int
    n_intervals: int


SETTINGS = [
    Setting("SB3 default nets (400-300), batch 256", [400, 300], 256, 100),
    Setting("shipped Pendulum nets (64-64), batch 256", [64, 64], 256, 100),
    Setting("paper Pendulum nets (30), batch 32", [30], 32, 100),
]


def make_model(algo: str, setting: Setting, env_id: str, seed: int) -> BaseAlgorithm:
    common: dict[str, Any] = dict(
        learning_rate=1e-3,
        buffer_size=100_000,
        learning_starts=setting.batch_size,
        batch_size=setting.batch_size,
        tau=0.01,
        gamma=0.99,
        train_freq=1,
        gradient_steps=1,
        seed=seed,
        device="cpu",
    )
    env = gym.make(env_id)
    if algo == "DDPG":
        return DDPG("MlpPolicy", env, policy_kwargs=dict(net_arch=setting.net_arch), **common)
    return ADC("MlpPolicy", env, policy_kwargs=dict(net_arch=setting.net_arch, n_intervals=setting.n_intervals), **common)


CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}


def time_training(make: Callable[[], BaseAlgorithm], steps: int, warmup: int, clock: Callable[[], float]) -> float:
    """Steps per second of ``learn(steps)`` after ``warmup`` steps (which fill the buffer past ``learning_starts``)."""
    model = make()
    model.learn(warmup)
    start = clock()
    model.learn(steps, reset_num_timesteps=False)
    return steps / (clock() - start)


def run(env_id: str, steps: int, warmup: int, repeats: int, clock: Callable[[], float]) -> list[dict[str, Any]]:
    rows = []
    for setting in SETTINGS:
        timings: dict[str, list[float]] = {"DDPG": [], "ADC": []}
        for repeat in range(repeats):
            order = ["DDPG", "ADC"] if repeat % 2 == 0 else ["ADC", "DDPG"]
            for algo in order:
                speed = time_training(partial(make_model, algo, setting, env_id, repeat), steps, warmup, clock)
                timings[algo].append(speed)
                print(f"  {setting.name:<40} {algo:<5} repeat {repeat}: {speed:8.1f} steps/s", flush=True)
        ddpg, adc = statistics.median(timings["DDPG"]), statistics.median(timings["ADC"])
        rows.append(
            dict(
                setting=setting.name,
                **asdict(setting),
                ddpg_steps_per_s=round(ddpg, 1),
                adc_steps_per_s=round(adc, 1),
                ratio_adc_over_ddpg=round(adc / ddpg, 3),
                ddpg_runs=[round(x, 1) for x in timings["DDPG"]],
                adc_runs=[round(x, 1) for x in timings["ADC"]],
            )
        )
    return rows


def print_table(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| setting | DDPG steps/s | ADC steps/s | ADC / DDPG |",
        "|---|---:|---:|---:|",
    ]
    lines += [
        f"| {r['setting']} | {r['ddpg_steps_per_s']:.0f} | {r['adc_steps_per_s']:.0f} | {r['ratio_adc_over_ddpg']:.2f} |"
        for r in rows
    ]
    table = "\n".join(lines)
    print(table)
    return table


def write_csv(rows: list[dict[str, Any]], path: Path) -> None:
    with path.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["setting", "DDPG steps/s", "ADC steps/s", "ADC / DDPG"])
        for r in rows:
            ddpg, adc, ratio = r["ddpg_steps_per_s"], r["adc_steps_per_s"], r["ratio_adc_over_ddpg"]
            writer.writerow([r["setting"], f"{ddpg:.0f}", f"{adc:.0f}", f"{ratio:.2f}"])


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """Per algorithm and setting: the median throughput (marker), the range over the repeats (whiskers), each repeat (dots)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 3.4))
    y = np.arange(len(rows))
    repeats = len(rows[0]["ddpg_runs"])
    for offset, label, key, color in ((-0.15, "SB3 DDPG", "ddpg", "#666666"), (0.15, "ADC", "adc", "#d95f02")):
        medians = np.array([r[f"{key}_steps_per_s"] for r in rows])
        runs = [np.asarray(r[f"{key}_runs"], dtype=float) for r in rows]
        whiskers = np.array([medians - [run.min() for run in runs], [run.max() for run in runs] - medians])
        ax.errorbar(medians, y + offset, xerr=whiskers, fmt="D", color=color, capsize=4, label=f"{label} (median, min-max)")
        for i, run in enumerate(runs):
            ax.plot(run, np.full(len(run), y[i] + offset), "o", color=color, markersize=3, alpha=0.5)
    for i, r in enumerate(rows):
        top = max(max(r["adc_runs"]), max(r["ddpg_runs"]))
        ax.text(top * 1.08, i, f"ADC / DDPG = {r['ratio_adc_over_ddpg']:.2f}", va="center", fontsize="small")
    ax.set_yticks(y, [r["setting"] for r in rows])
    ax.set_ylim(-0.6, len(rows) - 0.4)
    # The settings differ ten-fold in speed: a log axis shows each one's spread.
    ax.set_xscale("log")
    lowest = min(min(min(r["adc_runs"]), min(r["ddpg_runs"])) for r in rows)
    highest = max(max(max(r["adc_runs"]), max(r["ddpg_runs"])) for r in rows)
    ax.set_xlim(lowest * 0.8, highest * 2.2)
    ax.set_xlabel("training throughput (env steps/s, one update per step; log scale)")
    ax.set_title(f"{repeats} repeats per point, alternating algorithms; dots: each repeat", fontsize="small")
    ax.grid(alpha=0.3, axis="x", which="both")
    ax.legend(loc="lower right", fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="Pendulum-v1", help="environment id (default: Pendulum-v1)")
    parser.add_argument("--steps", type=int, default=3000, help="timed steps per run (default: 3000)")
    parser.add_argument("--warmup", type=int, default=500, help="untimed steps before timing (default: 500)")
    parser.add_argument("--repeats", type=int, default=5, help="runs per algorithm and setting (default: 5)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: 1)")
    parser.add_argument(
        "--clock",
        choices=sorted(CLOCKS),
        default="wall",
        help="wall: elapsed time (default; use an otherwise idle machine); cpu: this process' CPU time, robust to "
        "other load on a shared machine",
    )
    parser.add_argument("--quick", action="store_true", help="a short smoke run; writes nothing")
    parser.add_argument("--output", type=Path, default=RESULTS_DIR, help="results folder (default: benchmarks/results)")
    args = parser.parse_args()

    th.set_num_threads(args.threads)
    steps, warmup, repeats = (300, 300, 1) if args.quick else (args.steps, args.warmup, args.repeats)
    print(f"Training throughput on {args.env}: {steps} timed steps after {warmup}, {repeats} repeats, {args.clock} clock")
    rows = run(args.env, steps, warmup, repeats, CLOCKS[args.clock])
    table = print_table(rows)
    if args.quick:
        return
    args.output.mkdir(parents=True, exist_ok=True)
    result = dict(
        benchmark="training_throughput",
        env=args.env,
        timed_steps=steps,
        warmup_steps=warmup,
        repeats=repeats,
        torch_threads=args.threads,
        clock=args.clock,
        machine=dict(
            processor=platform.processor() or platform.machine(), cpu_count=os.cpu_count(), python=platform.python_version()
        ),
        versions=dict(sb3_adc=sb3_adc.__version__, stable_baselines3=stable_baselines3.__version__, torch=th.__version__),
        rows=rows,
    )
    (args.output / "training_throughput.json").write_text(json.dumps(result, indent=2) + "\n")
    (args.output / "training_throughput.md").write_text(table + "\n")
    write_csv(rows, args.output / "training_throughput.csv")
    plot(rows, args.output / "training_throughput.png")
    print(f"wrote {args.output}/training_throughput.{{json,md,csv,png}}")


if __name__ == "__main__":
    main()
