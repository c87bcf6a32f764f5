"""The wall-clock times of a whole shipped ``-v1`` run that the ADC page and the changelog quote are those of
``benchmarks/results/lidar_v1_wallclock/wallclock_curves.csv`` (each configuration's last row: its run's end)."""

from __future__ import annotations

import csv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CURVES = ROOT / "benchmarks" / "results" / "lidar_v1_wallclock" / "wallclock_curves.csv"


def _run_seconds() -> dict[str, float]:
    """Configuration -> wall-clock seconds at its run's last evaluation (the rows are in time order)."""
    with CURVES.open(encoding="utf-8") as stream:
        return {row["algo"]: float(row["wall_time_s"]) for row in csv.DictReader(stream)}


def test_the_adc_page_quotes_the_committed_wall_times() -> None:
    seconds = _run_seconds()
    plain, fast = seconds["adc_plain"], seconds["adc_fast"]
    page = " ".join((ROOT / "docs" / "modules" / "adc.rst").read_text(encoding="utf-8").split())
    assert f"took {round(plain):,} s with the plain update and {round(fast):,} s with ``fast_update``" in page
    assert f"about {round(plain / 60)} and {round(fast / 60)} minutes" in page


def test_the_changelog_quotes_the_committed_wall_times_in_minutes() -> None:
    seconds = _run_seconds()
    plain, fast = round(seconds["adc_plain"] / 60), round(seconds["adc_fast"] / 60)
    changelog = " ".join((ROOT / "docs" / "changelog.rst").read_text(encoding="utf-8").split())
    assert f"about {plain} minutes with the plain update and {fast} with" in changelog
