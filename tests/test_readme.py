"""The README's two set-up commands stay true (CI runs the test command verbatim); its links resolve; it stays short."""

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


def test_readme_links_point_to_files_in_the_repository():
    """Every relative link and image of the README names a committed file (the results pages, the docs)."""
    readme = (ROOT / "README.md").read_text()
    targets = [target for target in re.findall(r"\]\(([^)\s]+)\)", readme) if "://" not in target]
    assert "docs/results/which_algorithm.rst" in targets
    missing = [target for target in targets if not (ROOT / target.split("#", 1)[0]).is_file()]
    assert not missing


def test_readme_is_a_three_minute_read():
    """The README stays a product page: at most 1,200 words, as ``wc -w`` counts them."""
    assert len((ROOT / "README.md").read_text().split()) <= 1200
