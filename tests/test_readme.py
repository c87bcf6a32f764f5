"""The README's two set-up commands stay true: CI runs the test command verbatim."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def setup_commands():
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## Set-up", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```bash\n(.+?)\n```", section, flags=re.DOTALL)


def test_readme_has_exactly_two_setup_commands():
    commands = setup_commands()
    assert len(commands) == 2
    main, tests = commands
    assert "sb3-adc train --algo adc --env sb3_adc/NoisyPendulum-v1" in main
    assert "constraints.txt" in main
    assert "pytest" in tests
    assert "constraints.txt" in tests


def test_ci_runs_the_readme_test_command():
    _, tests = setup_commands()
    ci_lines = (ROOT / ".ci" / "run").read_text().splitlines()
    assert tests.strip() in [line.strip() for line in ci_lines]


def held_out_iqm(folder: str) -> dict[str, str]:
    """Algorithm -> held-out success IQM, as the committed ``success_rates.md`` of a procedural grid prints it."""
    table = (ROOT / "benchmarks" / "results" / "procedural_generalisation" / folder / "success_rates.md").read_text()
    rows = re.findall(r"^\| held-out layouts \| (\w+) \| \d+ \| ([\d.]+) \[", table, flags=re.MULTILINE)
    return dict(rows)


def test_readme_procedural_figures_are_the_committed_ones():
    """The held-out success rates the README quotes are those of the committed grids it names."""
    readme = " ".join((ROOT / "README.md").read_text().split())
    first = held_out_iqm("LidarObstacleCourse-v1_first_entries")
    quoted = ", ".join(f"{first[algo]} for {algo.upper()}" for algo in ("adc", "ddpg", "sac"))
    assert f"is {quoted} and {first['td3']} for TD3" in readme
    tuned = held_out_iqm("LidarObstacleCourse-v1_shaping_150k")
    assert f"ADC reaches {tuned['adc']} and TD3 {tuned['td3']}" in readme
    rates = held_out_iqm("LidarObstacleCourse-v1_td3_rates_150k")
    assert f"with TD3's learning rates ADC reaches {rates['adc']}" in readme
    selected = held_out_iqm("LidarObstacleCourse-v1_td3_rates_150k_validation_best")
    assert f"and {selected['adc']} with the model each of those runs selects by success" in readme
    winners = held_out_iqm("LidarObstacleCourse-v1_fair_tuning_lidar")
    assert f"reach {winners['td3']} for TD3, {winners['sac']} for SAC and {winners['ddpg']} for DDPG" in readme
    winner_selected = held_out_iqm("LidarObstacleCourse-v1_fair_tuning_lidar_validation_best")
    assert f"TD3's winner reaches {winner_selected['td3']} and DDPG's {winner_selected['ddpg']} " in readme
    assert f"against ADC's {selected['adc']}." in readme
