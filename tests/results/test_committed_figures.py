"""The committed results rebuild without retraining: ``sb3-adc plot`` on a grid's committed per-run CSVs gives the
numbers behind its committed figures."""

from pathlib import Path

import pandas as pd
import pytest

from sb3_adc.cli import main

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "benchmarks" / "results" / "noisy_pendulum_shipped"


def test_the_shipped_grid_learning_curves_rebuild_from_the_committed_csvs(tmp_path, capsys):
    # The experiments plot with 5000 bootstrap resamples from seed 0; each configuration is bootstrapped on its
    # own, so two of them rebuild their rows exactly.
    algos = ["adc_shipped", "ddpg_shipped"]
    args = ["plot", "--csv", str(SHIPPED / "evaluations.csv"), "-o", str(tmp_path), "--reps", "5000", "--algos", *algos]
    assert main(args) == 0
    assert (tmp_path / "learning_curves.png").stat().st_size > 10_000
    rebuilt = pd.read_csv(tmp_path / "curves.csv")
    committed = pd.read_csv(SHIPPED / "curves.csv")
    committed = committed[committed["algo"].isin(algos)].reset_index(drop=True)
    pd.testing.assert_frame_equal(rebuilt, committed, check_exact=False, rtol=1e-9)
    # The final-return table of the results page: the IQM of each configuration from the committed final.csv.
    summary = pd.read_csv(SHIPPED / "summary.csv").set_index("config")
    performance = pd.read_csv(tmp_path / "final_performance.csv").set_index("algo")
    for algo in algos:
        assert performance.loc[algo, "iqm"] == pytest.approx(summary.loc[algo, "final_iqm"])
    assert "| sb3_adc/NoisyPendulum-v1 | adc_shipped | 10 |" in capsys.readouterr().out
