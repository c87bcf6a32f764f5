"""
Training throughput of ADC, with each critic design, against SB3's DDPG, measured in the same run.

Throughput is environment steps per second of ``learn()`` past the warm-up, one gradient step per environment
step (``train_freq=1``), so it includes rollout collection, replay sampling and every update. Every model gets
identical layer sizes: the DDPG critic's hidden layers are ADC's shared trunk (``net_arch``), on top of which
each critic design (:data:`sb3_adc.adc.policies.CRITIC_DESIGNS`) adds its value and advantage outputs. Runs cycle
through the models in a rotating order so that drift of the machine's speed affects all alike; the median over
repeats is reported, and each design's ratio to DDPG.

Usage::

    python benchmarks/training_throughput.py            # full run, writes benchmarks/results/
    python benchmarks/training_throughput.py --quick    # a smoke run
    python benchmarks/training_throughput.py --n-intervals 20 60 100 140 --designs paper legendre
                                                        # the paper's setting at each interval count
    python benchmarks/training_throughput.py --fast-update --steps 2000 --warmup 500 --clock cpu
                                                        # ADC's fast and plain update paths, SB3's TD3 and DDPG,
                                                        # update_limit.py's loop; writes training_throughput_fast.*

The ``--fast-update`` mode times ADC with ``fast_update=True`` and ``False`` (the default) against SB3's TD3 and
DDPG with the update settings of the lidar ``-v1`` entries (``sb3_adc/LidarObstacleCourse-v1`` in
``hyperparams/adc.yml``: twin critics, policy delay 2, target smoothing, 3-step returns, ``tau=0.01``; ADC with its
averaged actor), at the entries' networks and batch and at two larger ones. TD3 gets the same settings (its
defaults, plus ``n_steps=3``); DDPG is SB3's (one critic, no delay, no smoothing) with the same networks, batch
and ``n_steps``.
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3 import DDPG, TD3
from stable_baselines3.common.base_class import BaseAlgorithm
from update_limit import TightLoop

from sb3_adc import ADC
from sb3_adc.adc.policies import CRITIC_DESIGNS, DEFAULT_BASIS_DEGREE, DEFAULT_CRITIC_DESIGN, validate_critic_options
from sb3_adc.experiment.provenance import machine_metadata

RESULTS_DIR = Path(__file__).parent / "results"

#: The settings of every timed model, with its batch (also ``learning_starts``), ``gamma`` and ``seed``.
COMMON: dict[str, Any] = dict(learning_rate=1e-3, buffer_size=100_000, tau=0.01, train_freq=1, gradient_steps=1, device="cpu")
#: ``"action_network"`` evaluates its advantage network at every interval centre, so its cost grows with
#: ``n_intervals``; it is timed with the 16 intervals it is used with in the critic study
#: (``benchmarks/experiments/critic_design_screen.yml``, configuration ``adc_action_network``).
ACTION_NETWORK_INTERVALS = 16


@dataclass(frozen=True)
class Setting:
    """One network size at which every model is timed."""

    name: str
    net_arch: list[int]
    batch_size: int
    n_intervals: int


SETTINGS = [
    Setting("SB3 default nets (400-300), batch 256", [400, 300], 256, 100),
    Setting("256-256 nets, batch 256", [256, 256], 256, 100),
    Setting("shipped Pendulum nets (64-64), batch 256", [64, 64], 256, 100),
    Setting("paper Pendulum nets (30), batch 32", [30], 32, 100),
]


def make_model(model: str, setting: Setting, env_id: str, seed: int) -> BaseAlgorithm:
    common = dict(COMMON, learning_starts=setting.batch_size, batch_size=setting.batch_size, gamma=0.99, seed=seed)
    env = gym.make(env_id)
    if model == "DDPG":
        return DDPG("MlpPolicy", env, policy_kwargs=dict(net_arch=setting.net_arch), **common)
    n_intervals = min(setting.n_intervals, ACTION_NETWORK_INTERVALS) if model == "action_network" else setting.n_intervals
    policy_kwargs = dict(net_arch=setting.net_arch, n_intervals=n_intervals, critic_design=model)
    return ADC("MlpPolicy", env, policy_kwargs=policy_kwargs, **common)


#: The models of ``--fast-update``; "tight loop" is :class:`update_limit.TightLoop`, the same update without SB3.
FAST_MODELS = ["ADC fast", "ADC plain", "TD3", "DDPG", "tight loop"]


@dataclass(frozen=True)
class FastSetting:
    """One network size at which ``--fast-update`` times every model."""

    name: str
    actor_arch: list[int]
    #: ADC's critic trunk; TD3's and DDPG's critic hidden layers are the trunk and then ``head_arch``
    critic_arch: list[int]
    #: ADC's value and advantage heads' hidden layers (the shipped ``-v1`` nets: ``[20]``)
    head_arch: list[int]
    batch_size: int


FAST_SETTINGS = [
    FastSetting("shipped -v1 nets (pi 100-20, qf 100 + heads 20), batch 64", [100, 20], [100], [20], 64),
    FastSetting("64-64 nets, batch 256", [64, 64], [64, 64], [], 256),
    FastSetting("256-256 nets, batch 256", [256, 256], [256, 256], [], 256),
]


def make_fast_model(model: str, setting: FastSetting, env_id: str, seed: int, **adc_options: Any) -> BaseAlgorithm:
    """A model of ``--fast-update``: the ``-v1`` entries' update settings (module docstring); ADC's plus ``adc_options``."""
    common = dict(COMMON, learning_starts=setting.batch_size, batch_size=setting.batch_size, gamma=0.98, n_steps=3, seed=seed)
    critic_layers = [*setting.critic_arch, *setting.head_arch]
    if model == "tight loop":
        return TightLoop(env_id, setting.actor_arch, critic_layers, setting.batch_size, seed)
    env = gym.make(env_id)
    baseline_arch = dict(pi=setting.actor_arch, qf=critic_layers)
    if model in ("TD3", "DDPG"):
        return {"TD3": TD3, "DDPG": DDPG}[model]("MlpPolicy", env, policy_kwargs=dict(net_arch=baseline_arch), **common)
    heads = dict(value_net_arch=setting.head_arch, advantage_net_arch=setting.head_arch, actor_average_tau=1e-4)
    policy_kwargs = dict(net_arch=dict(pi=setting.actor_arch, qf=setting.critic_arch), n_critics=2, n_intervals=100, **heads)
    update: dict[str, Any] = dict(critic_learning_rate=1e-3, policy_delay=2, target_policy_noise=0.2, target_noise_clip=0.5)
    update |= adc_options
    return ADC("MlpPolicy", env, fast_update=model == "ADC fast", policy_kwargs=policy_kwargs, **update, **common)


CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}
#: A model's maker: (model, setting, env id, seed) -> the model.
Maker = Callable[[str, Any, str, int], BaseAlgorithm]


def time_training(make: Callable[[], BaseAlgorithm], args: argparse.Namespace) -> float:
    """
    Steps per second of ``learn(args.steps)`` after ``args.warmup`` steps (which fill the buffer past
    ``learning_starts``), on ``args.clock``: SB3's ``learn`` itself, without the engine's evaluations and files.
    """
    model, clock = make(), CLOCKS[args.clock]
    model.learn(args.warmup)
    start = clock()
    model.learn(args.steps, reset_num_timesteps=False)
    return args.steps / (clock() - start)


def run(
    args: argparse.Namespace, models: list[str], settings: Sequence[Any], make: Maker, baseline: str
) -> list[dict[str, Any]]:
    """
    Time ``models`` at each setting (``args``: ``env``, ``steps``, ``warmup``, ``repeats``, ``clock``), in a rotating
    order: per model the median steps/s, the repeats, and the ratio of medians to ``baseline``
    (``{model}_over_{baseline}``, spaces in names as ``_``).
    """
    rows = []
    for setting in settings:
        timings: dict[str, list[float]] = {model: [] for model in models}
        for repeat in range(args.repeats):
            shift = repeat % len(models)
            for model in models[shift:] + models[:shift]:
                speed = time_training(partial(make, model, setting, args.env, repeat), args)
                timings[model].append(speed)
                print(f"  {setting.name:<58} {model:<15} repeat {repeat}: {speed:8.1f} steps/s", flush=True)
        reference = statistics.median(timings[baseline])
        row: dict[str, Any] = dict(setting=setting.name, **asdict(setting))
        for model in models:
            key, median = model.replace(" ", "_"), statistics.median(timings[model])
            row[f"{key}_steps_per_s"] = round(median, 1)
            row[f"{key}_runs"] = [round(x, 1) for x in timings[model]]
            row[f"{key}_over_{baseline.lower()}"] = round(median / reference, 3)
        rows.append(row)
    return rows


def speed_cell(row: dict[str, Any], model: str, baseline: str) -> str:
    """``model``'s median steps/s in a :func:`run` row, [min-max over the repeats] (ratio of medians to ``baseline``)."""
    key = model.replace(" ", "_")
    runs = row[f"{key}_runs"]
    return f"{row[f'{key}_steps_per_s']:.0f} [{min(runs):.0f}-{max(runs):.0f}] ({row[f'{key}_over_{baseline.lower()}']:.2f})"


def fast_cells(rows: list[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """The ``--fast-update`` table's header and rows: median steps/s [min-max over the repeats] (ratio to TD3's)."""
    labels = {"ADC fast": "ADC fast_update", "ADC plain": "ADC plain", "TD3": "SB3 TD3", "DDPG": "SB3 DDPG"}
    header = ["setting", *(f"{labels.get(m, m)} steps/s (/ TD3)" for m in FAST_MODELS), "ADC fast / plain"]
    header.append("ADC fast / tight loop")
    body = []
    for r in rows:
        cells = [r["setting"], *(speed_cell(r, model, "TD3") for model in FAST_MODELS)]
        cells += [f"{r['ADC_fast_steps_per_s'] / r[f'{m}_steps_per_s']:.2f}" for m in ("ADC_plain", "tight_loop")]
        body.append(cells)
    return header, body


def _label(model: str) -> str:
    return "SB3 DDPG" if model == "DDPG" else f"ADC {model}" + (" (default)" if model == DEFAULT_CRITIC_DESIGN else "")


def cells(rows: list[dict[str, Any]], models: list[str]) -> tuple[list[str], list[list[str]]]:
    """The table's header and rows: DDPG's median steps/s, then each design's (and its ratio to DDPG's)."""
    designs = [model for model in models if model != "DDPG"]
    header = ["setting", "SB3 DDPG steps/s", *(f"{_label(d)} steps/s (/ DDPG)" for d in designs)]
    body = []
    for r in rows:
        ratios = [f"{r[f'{d}_steps_per_s']:.0f} ({r[f'{d}_over_ddpg']:.2f})" for d in designs]
        body.append([r["setting"], f"{r['DDPG_steps_per_s']:.0f}", *ratios])
    return header, body


def print_table(header: list[str], body: list[list[str]]) -> str:
    """Print the table in Markdown, and return it."""
    lines = ["| " + " | ".join(header) + " |", "|---|" + "---:|" * (len(header) - 1)]
    lines += ["| " + " | ".join(row) + " |" for row in body]
    table = "\n".join(lines)
    print(table)
    return table


def write_tables(output: Path, stem: str, table: str, header: list[str], body: list[list[str]], note: str = "") -> None:
    """Write ``{stem}.md`` (the Markdown ``table``, then ``note``) and ``{stem}.csv`` (``header`` and ``body``)."""
    (output / f"{stem}.md").write_text(table + "\n" + note)
    with (output / f"{stem}.csv").open("w", newline="") as file:
        csv.writer(file).writerows([header, *body])


def timing_note(result: dict[str, Any], baseline: str, warmup: str = "", tail: str = ".") -> str:
    """The protocol line under a throughput table, from :func:`record`'s ``result``, ``warmup`` and ``tail`` inserted."""
    return (
        f"\n{result['env']}, {result['timed_steps']} timed environment steps after {result['warmup_steps']}{warmup}, one "
        f"gradient step per step, {result['repeats']} repeats in a rotating order, {result['torch_threads']} torch thread(s), "
        f"{result['clock']} clock, torch {result['versions']['torch']}, {result['machine'].get('cpu', 'processor unrecorded')}"
        f"; median steps/s [min-max] (ratio of medians to SB3 {baseline}){tail}\n"
    )


def write_fast(result: dict[str, Any], output: Path) -> None:
    """Write ``training_throughput_fast.{md,csv}`` from the results' JSON (``result``)."""
    header, body = fast_cells(result["rows"])
    write_tables(output, "training_throughput_fast", print_table(header, body), header, body, timing_note(result, "TD3"))


def plot(rows: list[dict[str, Any]], models: list[str], path: Path) -> None:
    """Per model and setting: the median throughput (marker), the range over the repeats (whiskers), each repeat (dots)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 1.5 + 0.28 * len(rows) * len(models)))
    y = np.arange(len(rows))
    repeats = len(rows[0]["DDPG_runs"])
    colors = ["#666666", "#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e"]
    height = 0.8 / len(models)
    for index, model in enumerate(models):
        offset = (index - (len(models) - 1) / 2) * height
        medians = np.array([r[f"{model}_steps_per_s"] for r in rows])
        runs = [np.asarray(r[f"{model}_runs"], dtype=float) for r in rows]
        whiskers = np.array([medians - [run.min() for run in runs], [run.max() for run in runs] - medians])
        color = colors[index % len(colors)]
        label = f"{_label(model)} (median, min-max)"
        ax.errorbar(medians, y + offset, xerr=whiskers, fmt="D", color=color, capsize=3, markersize=4, label=label)
        for i, run in enumerate(runs):
            ax.plot(run, np.full(len(run), y[i] + offset), "o", color=color, markersize=2.5, alpha=0.5)
    for i, r in enumerate(rows):
        top = max(max(r[f"{model}_runs"]) for model in models)
        ratio = r.get(f"{DEFAULT_CRITIC_DESIGN}_over_ddpg")
        if ratio is not None:
            ax.text(top * 1.08, i, f"default / DDPG = {ratio:.2f}", va="center", fontsize="small")
    ax.set_yticks(y, [r["setting"] for r in rows])
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.set_xscale("log")  # the settings differ ten-fold in speed: a log axis shows each one's spread
    lowest = min(min(r[f"{model}_runs"]) for r in rows for model in models)
    highest = max(max(r[f"{model}_runs"]) for r in rows for model in models)
    ax.set_xlim(lowest * 0.8, highest * 4.0)
    ax.set_xlabel("training throughput (env steps/s, one update per step; log scale)")
    ax.set_title(f"{repeats} repeats per point, rotating order; dots: each repeat", fontsize="small")
    ax.grid(alpha=0.3, axis="x", which="both")
    fig.tight_layout()
    # Below the figure (kept by the tight bounding box), where it covers neither the points nor the ratio labels.
    fig.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2, fontsize="x-small")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def timing_parser(description: str, steps: int, warmup: int, clock: str) -> argparse.ArgumentParser:
    """A parser with the options every throughput script shares (steps, warm-up, repeats, threads, clock, output)."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=steps, help=f"timed steps per run (default: {steps})")
    parser.add_argument("--warmup", type=int, default=warmup, help=f"untimed steps before timing (default: {warmup})")
    parser.add_argument("--repeats", type=int, default=3, help="runs per model and setting (default: 3)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: 1)")
    clocks = "wall: elapsed time (use an idle machine); cpu: this process' CPU time, robust to other load"
    parser.add_argument("--clock", choices=sorted(CLOCKS), default=clock, help=f"{clocks} (default: {clock})")
    parser.add_argument("--quick", action="store_true", help="a short smoke run; writes nothing")
    parser.add_argument("--output", type=Path, default=RESULTS_DIR, help="results folder (default: benchmarks/results)")
    return parser


def main() -> None:
    parser = timing_parser(__doc__ or "", steps=1500, warmup=300, clock="wall")
    parser.add_argument("--env", default="Pendulum-v1", help="environment id (default: Pendulum-v1)")
    parser.add_argument(
        "--designs", nargs="+", choices=CRITIC_DESIGNS, default=list(CRITIC_DESIGNS), help="ADC critic designs (default: all)"
    )
    parser.add_argument(
        "--n-intervals",
        type=int,
        nargs="+",
        metavar="N",
        help="time the paper's Pendulum setting (30 units, batch 32) at each of these interval counts instead of the "
        "network sizes; writes training_throughput_intervals.*",
    )
    parser.add_argument(
        "--fast-update",
        action="store_true",
        help="time ADC's fast update path against its plain path, SB3 TD3 and SB3 DDPG with the -v1 update "
        "settings; writes training_throughput_fast.*",
    )
    parser.add_argument(
        "--replot",
        action="store_true",
        help="redraw the figure from the results' JSON, without timing (with --fast-update: rewrite its .md and .csv)",
    )
    args = parser.parse_args()

    if args.fast_update and args.replot:
        write_fast(json.loads((args.output / "training_throughput_fast.json").read_text()), args.output)
        return
    stem = "training_throughput_intervals" if args.n_intervals else "training_throughput"
    if args.replot:
        saved = json.loads((args.output / f"{stem}.json").read_text())
        plot(saved["rows"], ["DDPG", *saved["designs"]], args.output / f"{stem}.png")
        return
    settings: Sequence[Any] = SETTINGS
    if args.n_intervals:
        for n in args.n_intervals:
            try:
                validate_critic_options(DEFAULT_CRITIC_DESIGN, n, "mean", "none", DEFAULT_BASIS_DEGREE, 1)
            except ValueError as error:
                parser.error(f"--n-intervals: {error}")
        base = SETTINGS[-1]
        settings = [replace(base, name=f"{base.name}, {n} intervals", n_intervals=n) for n in args.n_intervals]
    th.set_num_threads(args.threads)
    if args.quick:
        args.steps, args.warmup, args.repeats = 300, 300, 1
    timing = f"{args.steps} timed steps after {args.warmup}, {args.repeats} repeats, {args.clock} clock"
    if args.fast_update:
        print(f"Fast update on {args.env}: {timing}")
        settings = FAST_SETTINGS[:1] if args.quick else FAST_SETTINGS
        rows = run(args, FAST_MODELS, settings, make_fast_model, "TD3")
        if args.quick:
            print_table(*fast_cells(rows))
            return
        write_fast(record("training_throughput --fast-update", args, rows, models=FAST_MODELS), args.output)
        print(f"wrote {args.output}/training_throughput_fast.{{json,md,csv}}")
        return
    print(f"Training throughput on {args.env}: {timing}")
    models = ["DDPG", *args.designs]
    settings = settings[-1:] if args.quick else settings
    rows = run(args, models, settings, make_model, "DDPG")
    header, body = cells(rows, models)
    table = print_table(header, body)
    if args.quick:
        return
    extra = dict(action_network_intervals=ACTION_NETWORK_INTERVALS, designs=args.designs)
    record("training_throughput", args, rows, stem, **extra, default_critic_design=DEFAULT_CRITIC_DESIGN)
    write_tables(args.output, stem, table, header, body)
    plot(rows, models, args.output / f"{stem}.png")
    print(f"wrote {args.output}/{stem}.{{json,md,csv,png}}")


def record(
    benchmark: str, args: argparse.Namespace, rows: list[Any], stem: str = "training_throughput_fast", **settings: Any
) -> Any:
    """Write the results' JSON (``{stem}.json``: the settings, the machine, the versions and the rows); return it."""
    # The engine's provenance (processor model included: speeds and float rounding differ across processors), in
    # this JSON's two records.
    meta = machine_metadata()
    result = dict(
        benchmark=benchmark,
        env=args.env,
        timed_steps=args.steps,
        warmup_steps=args.warmup,
        repeats=args.repeats,
        torch_threads=args.threads,
        clock=args.clock,
        **settings,
        machine={"processor": meta["machine"], **{key: meta[key] for key in ("cpu", "cpu_count", "python")}},
        versions={key: meta[key] for key in ("sb3_adc", "stable_baselines3", "torch")},
        rows=rows,
    )
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / f"{stem}.json").write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
