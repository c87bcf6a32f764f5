"""The generated results table (``benchmarks/tables.py``): committed, reproducible, and embedded in the README."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
TABLES = ROOT / "docs" / "results" / "tables"


@pytest.fixture(scope="module")
def tables() -> ModuleType:
    """``benchmarks/tables.py``, loaded from its file (``tables`` is also PyTables' import name)."""
    spec = importlib.util.spec_from_file_location("benchmarks_tables", ROOT / "benchmarks" / "tables.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_regenerated_tables_are_the_committed_ones(tables: ModuleType, tmp_path: Path):
    written = tables.write_tables(tmp_path)
    names = sorted(path.name for path in written)
    assert names == ["probabilities.csv", "probabilities.md", "tasks.csv", "tasks.md"]
    for name in names:
        assert (tmp_path / name).read_text() == (TABLES / name).read_text(), name


@pytest.mark.parametrize(
    ("low", "high", "expected"),
    [
        (0.27, 0.79, "level with"),
        (0.5, 0.9, "level with"),
        (0.1, 0.5, "level with"),
        (0.04, 0.49, "behind"),
        (0.51, 0.99, "ahead of"),
    ],
)
def test_relation_follows_the_ci_of_p_adc(tables: ModuleType, low: float, high: float, expected: str):
    assert tables.relation(low, high) == expected


def test_verdict_groups_the_algorithms(tables: ModuleType):
    verdict = tables.verdict
    level = (0.5, 0.3, 0.7)
    behind = (0.2, 0.05, 0.45)
    ahead = (0.8, 0.6, 0.95)
    assert verdict({"DDPG": level, "TD3": level, "SAC": level}) == "ADC level with DDPG, TD3 and SAC"
    assert verdict({"DDPG": level, "TD3": behind, "SAC": ahead}) == "ADC ahead of SAC, level with DDPG, behind TD3"
    assert verdict({"DDPG": level, "TD3": level, "SAC": behind}) == "ADC level with DDPG and TD3, behind SAC"
    assert verdict({}) == tables.MISSING


def test_an_algorithm_not_run_is_a_dash(tables: ModuleType, monkeypatch: pytest.MonkeyPatch):
    (pendulum, *_) = tables.TASKS
    without_sac = tables.Task(pendulum.label, pendulum.metric, pendulum.summary, {"ADC": "adc_shipped", "TD3": "td3_tuned"})
    monkeypatch.setattr(tables, "TASKS", (without_sac,))
    rows, probabilities = tables.tables()
    header, row = rows
    assert row[header.index("SAC")] == row[header.index("DDPG")] == tables.MISSING
    assert row[-1] == "ADC level with TD3"
    assert probabilities[1][1:] == [tables.MISSING, "0.49 [0.22, 0.75]", tables.MISSING]


def test_cells_are_formatted_as_the_summaries_format_them(tables: ModuleType):
    """Every cell of the tasks table appears verbatim in the ``summary.md`` beside the summary it was read from."""
    rows = (TABLES / "tasks.md").read_text().splitlines()[2:]
    assert len(rows) == len(tables.TASKS)
    for line, task in zip(rows, tables.TASKS, strict=True):
        summary_md = (tables.RESULTS_DIR / task.summary).with_suffix(".md").read_text()
        cells = [cell.strip() for cell in line.strip("|").split("|")]
        assert cells[0] == task.label
        for cell in cells[2:6]:
            assert cell in summary_md, (task.label, cell)


def test_readme_embeds_the_table_verbatim():
    readme = (ROOT / "README.md").read_text()
    embedded = re.search(r"<!-- tasks-table:start -->\n(.*?)<!-- tasks-table:end -->", readme, flags=re.DOTALL)
    assert embedded is not None
    assert embedded.group(1) == (TABLES / "tasks.md").read_text()


def test_results_page_shows_the_generated_tables():
    page = (ROOT / "docs" / "results" / "which_algorithm.rst").read_text()
    assert ":file: tables/tasks.csv" in page
    assert ":file: tables/probabilities.csv" in page
