"""The results that moved to the git history are cited as ``git show COMMIT:PATH``: each citation must resolve."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CITATION = re.compile(r"git show ([0-9a-f]{7,40}):([\w./-]+)")


def citations() -> list[tuple[str, str, str]]:
    found = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.rst")), *sorted((ROOT / "hyperparams").rglob("*.yml"))]:
        found += [(str(page.relative_to(ROOT)), commit, path) for commit, path in CITATION.findall(page.read_text())]
    return found


def test_there_are_citations():
    assert citations()


@pytest.mark.parametrize(("page", "commit", "path"), citations())
def test_each_citation_names_a_file_or_folder_of_its_commit(page, commit, path):
    shallow = subprocess.run(["git", "rev-parse", "--is-shallow-repository"], cwd=ROOT, capture_output=True, text=True)
    if shallow.returncode != 0 or shallow.stdout.strip() != "false":
        pytest.skip("needs the repository's full history")
    found = subprocess.run(["git", "cat-file", "-e", f"{commit}:{path.rstrip('/')}"], cwd=ROOT, capture_output=True)
    assert found.returncode == 0, f"{page}: git show {commit}:{path} names nothing"
