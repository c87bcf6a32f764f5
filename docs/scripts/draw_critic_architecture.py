"""
Draw the dueling interval critic of ADC (docs/_static/adc_critic_architecture.png).

Usage::

    python docs/scripts/draw_critic_architecture.py
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

OUTPUT = Path(__file__).resolve().parents[1] / "_static" / "adc_critic_architecture.png"

COLOURS = {
    "input": "#e8e8e8",
    "actor": "#a6cee3",
    "trunk": "#fdbf6f",
    "value": "#b2df8a",
    "advantage": "#fb9a99",
    "aggregate": "#cab2d6",
}


def box(ax: plt.Axes, x: float, y: float, w: float, h: float, text: str, colour: str) -> None:
    ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.02,rounding_size=0.08", fc=colour, ec="#333333"))
    ax.text(x + w / 2, y + h / 2, text, ha="center", va="center", fontsize=9)


def arrow(ax: plt.Axes, start: tuple[float, float], end: tuple[float, float], text: str = "") -> None:
    ax.add_patch(FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=12, color="#333333", lw=1.2))
    if text:
        ax.text((start[0] + end[0]) / 2 + 0.05, (start[1] + end[1]) / 2, text, fontsize=8, color="#333333")


def draw() -> None:
    fig, ax = plt.subplots(figsize=(10, 5.2))
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 5.4)
    ax.axis("off")

    box(ax, 0.2, 4.3, 1.6, 0.7, "observation s\n(features extractor)", COLOURS["input"])
    box(ax, 0.2, 2.6, 1.6, 1.0, "actor mu(s)\nnet_arch['pi']\ntanh -> [-1, 1]", COLOURS["actor"])
    box(ax, 0.2, 1.0, 1.6, 0.9, "action a\n(replay, or mu(s)\nfor the actor loss)", COLOURS["input"])
    arrow(ax, (1.0, 4.3), (1.0, 3.6))
    arrow(ax, (1.0, 2.6), (1.0, 1.9))

    box(ax, 2.5, 2.3, 1.8, 1.2, "shared trunk theta^Q\nover [features, a]\nnet_arch['qf']", COLOURS["trunk"])
    arrow(ax, (1.8, 4.6), (2.6, 3.5), "s")
    arrow(ax, (1.8, 1.45), (2.6, 2.3), "a")

    box(ax, 5.0, 3.6, 2.0, 1.0, "value stream beta\nvalue_net_arch -> 1\nV(s)", COLOURS["value"])
    advantage_text = "advantage stream alpha\nadvantage_net_arch ->\naction_dim x n_intervals\nA(s, z_1) ... A(s, z_n)"
    box(ax, 5.0, 1.0, 2.0, 1.4, advantage_text, COLOURS["advantage"])
    arrow(ax, (4.3, 3.2), (5.0, 4.0))
    arrow(ax, (4.3, 2.6), (5.0, 1.9))

    box(ax, 5.0, 0.1, 2.0, 0.6, "interval z_a containing a\n(uniform partition of [-1, 1])", COLOURS["input"])
    arrow(ax, (1.8, 1.1), (5.0, 0.4))

    box(
        ax,
        7.5,
        2.0,
        1.9,
        1.6,
        "aggregation (Eq. 13-14)\nQ = V + sum_d [A_d(s, z_a)\n     - mean_z A_d(s, z)]\n(max_z for Eq. 11)",
        COLOURS["aggregate"],
    )
    arrow(ax, (7.0, 4.1), (8.2, 3.6), "V")
    arrow(ax, (7.0, 1.7), (7.5, 2.4), "A")
    arrow(ax, (7.0, 0.4), (8.4, 2.0), "z_a")
    arrow(ax, (9.4, 2.8), (9.95, 2.8))
    ax.text(9.7, 2.0, "Q(s, a)\none per\ncritic", fontsize=9, ha="center")

    ax.set_title("ADC's dueling interval critic (DuelingIntervalCritic)", fontsize=11)
    fig.tight_layout()
    OUTPUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUTPUT, dpi=130)
    plt.close(fig)
    print(f"wrote {OUTPUT}")


if __name__ == "__main__":
    draw()
