"""
What do ADC's mechanisms that use every interval at once cost? Training throughput against SB3's DDPG and TD3.

Times ``learn()`` of ADC as shipped (the plain update path), ADC with each of its three interval mechanisms on at
the values the screens used (greedy bootstrap targets ``target_greedy_mix=0.5``, the greedy actor
``actor_greedy_weight=0.1``, exploration from the advantages ``interval_exploration=0.2``), SB3's TD3 and SB3's
DDPG, with the settings and protocol of ``training_throughput.py --fast-update`` (the lidar ``-v1`` entries' update
settings and 100 intervals; steps/s past the warm-up, repeats in a rotating order, one torch thread), on a task
with one action dimension (Pendulum-v1) and one with six (HalfCheetah-v5, ``pip install "sb3-adc[mujoco]"``): the
greedy search is ``n_intervals`` columns per action dimension.

Usage::

    python benchmarks/mechanism_throughput.py          # writes benchmarks/results/training_throughput_mechanisms.*
    python benchmarks/mechanism_throughput.py --quick  # a smoke run, nothing written
"""

from __future__ import annotations

from typing import Any

import torch as th
import training_throughput as tt
from stable_baselines3.common.base_class import BaseAlgorithm

#: Each timed ADC model's options (the values of ``benchmarks/experiments/interval_mechanisms.yml``).
MECHANISMS: dict[str, dict[str, Any]] = {
    "ADC": {},
    "ADC greedy targets": {"target_greedy_mix": 0.5},
    "ADC greedy actor": {"actor_greedy_weight": 0.1},
    "ADC interval exploration": {"interval_exploration": 0.2, "interval_temperature": 10.0},
}
MODELS = ["DDPG", "TD3", *MECHANISMS]
ENVS = ["Pendulum-v1", "HalfCheetah-v5"]


def make(model: str, setting: tt.FastSetting, env_id: str, seed: int) -> BaseAlgorithm:
    """A model of :data:`MODELS`: SB3's DDPG or TD3, or ADC (plain update path) with a mechanism's options."""
    if model in MECHANISMS:
        return tt.make_fast_model("ADC plain", setting, env_id, seed, **MECHANISMS[model])
    return tt.make_fast_model(model, setting, env_id, seed)


def main() -> None:
    parser = tt.timing_parser(__doc__.split("\n\n")[1], steps=1500, warmup=300, clock="cpu")
    args = parser.parse_args()
    th.set_num_threads(args.threads)
    settings = tt.FAST_SETTINGS[:2]
    if args.quick:
        settings, args.steps, args.warmup, args.repeats = settings[:1], 200, 100, 1
    rows: list[dict[str, Any]] = []
    for env_id in ENVS:
        args.env = env_id
        rows += [dict(row, env=env_id) for row in tt.run(args, MODELS, settings, make, "DDPG")]
    header = ["env", "setting", *(f"{model} steps/s (/ DDPG)" for model in MODELS)]
    body = [[row["env"], row["setting"], *(tt.speed_cell(row, model, "DDPG") for model in MODELS)] for row in rows]
    table = tt.print_table(header, body)
    if args.quick:
        return
    stem = "training_throughput_mechanisms"
    args.env = ", ".join(ENVS)
    result = tt.record("mechanism_throughput", args, rows, stem, mechanisms=MECHANISMS)
    note = tt.timing_note(result, "DDPG", tail=". ADC: the plain update path, 100 intervals.")
    tt.write_tables(args.output, stem, table, header, body, note)
    print(f"wrote {args.output}/{stem}.{{json,md,csv}}")


if __name__ == "__main__":
    main()
