"""
Does ``torch.compile`` speed up ADC's fast update path on the CPU? (Issue 61 asks for it where it measurably helps.)

Times ``learn()`` of ADC with ``fast_update=True`` as it ships, the same model with the update's three graphs
compiled by ``torch.compile`` (the TD targets, the critics' Q-values and the actor loss, inductor's default mode,
static shapes), and SB3's TD3, with the settings and protocol of ``training_throughput.py --fast-update`` (the
``-v1`` update settings; steps/s past the warm-up, whose first gradient step compiles; repeats in a rotating order,
one torch thread). Also reports how long the warm-up took, which holds the compilation.

Usage::

    python benchmarks/compile_throughput.py          # writes benchmarks/results/training_throughput_compile.*
    python benchmarks/compile_throughput.py --quick  # a smoke run, nothing written
"""

from __future__ import annotations

import time
from typing import Any

import torch as th
import training_throughput as tt
from stable_baselines3.common.base_class import BaseAlgorithm

MODELS = ["ADC fast", "ADC fast compiled", "TD3"]
#: Seconds of each model's warm-up ``learn`` (the compilation included), by (setting, model).
WARMUP_S: dict[tuple[str, str], list[float]] = {}


def make(model: str, setting: tt.FastSetting, env_id: str, seed: int) -> BaseAlgorithm:
    """A model of :data:`MODELS`; the compiled one has its update's graphs wrapped in ``torch.compile``."""
    built = tt.make_fast_model("ADC fast" if model.startswith("ADC") else model, setting, env_id, seed)
    if model == "ADC fast compiled":
        for name in ("target_q_values", "_q_values", "actor_loss"):
            setattr(built, name, th.compile(getattr(built, name), dynamic=False))
    learn = built.learn

    def timed_learn(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        result = learn(*args, **kwargs)
        if kwargs.get("reset_num_timesteps", True):  # the warm-up
            WARMUP_S.setdefault((setting.name, model), []).append(round(time.perf_counter() - start, 1))
        return result

    built.learn = timed_learn
    return built


def main() -> None:
    parser = tt.timing_parser(__doc__.split("\n\n")[1], steps=2000, warmup=500, clock="cpu")
    parser.add_argument("--env", default="Pendulum-v1", help="environment id (default: Pendulum-v1)")
    args = parser.parse_args()
    th.set_num_threads(args.threads)
    settings = [tt.FAST_SETTINGS[0], tt.FAST_SETTINGS[2]]
    if args.quick:
        settings, args.steps, args.warmup, args.repeats = settings[:1], 200, 100, 1
    rows = tt.run(args, MODELS, settings, make, "TD3")
    for row in rows:
        row["warmup_s"] = {model: WARMUP_S[(row["setting"], model)] for model in MODELS}
    header = ["setting", *(f"{model} steps/s (/ TD3)" for model in MODELS), "compiled / fast", "warm-up s (fast, compiled)"]
    body = []
    for row in rows:
        cells = [tt.speed_cell(row, model, "TD3") for model in MODELS]
        ratio = row["ADC_fast_compiled_steps_per_s"] / row["ADC_fast_steps_per_s"]
        warmups = row["warmup_s"]
        warmup = f"{max(warmups['ADC fast']):.0f}, {max(warmups['ADC fast compiled']):.0f}"
        body.append([row["setting"], *cells, f"{ratio:.2f}", warmup])
    table = tt.print_table(header, body)
    if args.quick:
        return
    stem = "training_throughput_compile"
    result = tt.record("compile_throughput", args, rows, stem, compiled=["target_q_values", "_q_values", "actor_loss"])
    compilation, tail = " (the warm-up holds the compilation)", "; warm-up: the longest of the repeats, wall-clock seconds."
    note = tt.timing_note(result, "TD3", compilation, tail)
    tt.write_tables(args.output, stem, table, header, body, note)
    print(f"wrote {args.output}/{stem}.{{json,md,csv}}")


if __name__ == "__main__":
    main()
