"""
No result number typed by hand: every decimal number in the prose of the README (after its set-up section) and of
the results pages (``docs/results/*.rst``) appears in a generated table the document references.

A document references a table file by naming it: ``.. csv-table::``'s ``:file:`` and ``.. include::`` targets
(relative to the page), any ``benchmarks/results/...`` path written in it (a file, or every ``.csv``/``.md`` under
a folder), and, for the README, ``docs/results/tables/``. Code is not prose: fenced blocks and inline code in the
README; literal blocks (``::``), code blocks and ``inline literals`` in rst. Neither are URLs. A number matches a
number of the table files exactly, as the same pattern finds it there (``-153.4`` does not match ``-153.40857``).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: A decimal number, not part of a word, a longer number or a version (``2.13.0``); a sentence's full stop may follow.
NUMBER = re.compile(r"(?<![\w.])-?\d+\.\d+(?!\d|\.\d)")
URL = re.compile(r"https?://[^\s)>`]+")
#: A reference to the paper's sections, equations, figures and tables (``Section 5.2``, ``§5.1.1``): not a result.
REFERENCE = re.compile(r"(?:§\s*|\b(?:Sections?|Eqs?\.|Figs?\.|Figures?|Tables?)\s+)\d+(?:\.\d+)*")
RESULTS_PATH = re.compile(r"benchmarks/results/[\w./-]*[\w/]")
CODE_DIRECTIVE = re.compile(r"^\s*\.\. (code-block|code|sourcecode|literalinclude)::")
DOCUMENTS = ["README.md", *sorted(str(path.relative_to(ROOT)) for path in (ROOT / "docs" / "results").glob("*.rst"))]


def numbers(text: str) -> list[str]:
    """The decimal numbers of ``text``, with the typographic minus read as ``-``."""
    return NUMBER.findall(REFERENCE.sub(" ", URL.sub(" ", text.replace("\u2212", "-"))))


def readme_prose(text: str) -> str:
    """The README after its set-up section, without fenced code blocks and inline code."""
    after = text.split("## Set-up", 1)[1].split("\n## ", 1)[1]
    return re.sub(r"`[^`\n]*`", " ", re.sub(r"```.*?```", " ", after, flags=re.DOTALL))


def rst_prose(text: str) -> str:
    """An rst page without its literal blocks, code blocks and inline literals."""
    kept: list[str] = []
    skip_deeper_than: int | None = None
    for line in text.splitlines():
        indent = len(line) - len(line.lstrip())
        if skip_deeper_than is not None:
            if not line.strip() or indent > skip_deeper_than:
                continue
            skip_deeper_than = None
        literal = line.rstrip().endswith("::") and not line.lstrip().startswith(".. ")
        if literal or CODE_DIRECTIVE.match(line):
            skip_deeper_than = indent
            line = line.rstrip().removesuffix("::")
            if CODE_DIRECTIVE.match(line):
                continue
        kept.append(line)
    return re.sub(r"``.*?``", " ", "\n".join(kept), flags=re.DOTALL)


def referenced_tables(document: Path, text: str) -> list[Path]:
    """The table files ``document`` references (see the module's docstring)."""
    targets = [document.parent / target for target in re.findall(r"^\s*(?::file:|\.\. include::)\s*(\S+)", text, re.M)]
    targets += [ROOT / path for path in RESULTS_PATH.findall(text)]
    if document.name == "README.md":
        targets.append(ROOT / "docs" / "results" / "tables")
    files: list[Path] = []
    for target in targets:
        if target.is_dir():
            files += sorted(path for path in target.rglob("*") if path.suffix in (".csv", ".md"))
        elif target.is_file():
            files.append(target)
    return files


def test_the_patterns_find_what_they_should():
    assert numbers("IQM -153.4 [-167.5, -142.7]; torch 2.13.0, 0.94. Then \u2212150.6") == [
        "-153.4",
        "-167.5",
        "-142.7",
        "0.94",
        "-150.6",
    ]
    assert numbers("see https://doi.org/10.3390/s19071547 and 2e-4, 20,000 or 90%") == []
    assert numbers("the paper's Section 5.2, §5.1.1 and Table 1.5 but 0.6") == ["0.6"]
    prose = rst_prose("A 0.5 claim::\n\n    1.5 literal\n\n.. code-block:: bash\n\n    2.5\n\nBack, ``3.5``, 4.5.\n")
    assert numbers(prose) == ["0.5", "4.5"]
    readme = "## Set-up\n\n1.1 quoted\n\n## Results\n\n2.2 and `3.3`\n\n```bash\n4.4\n```\n"
    assert numbers(readme_prose(readme)) == ["2.2"]


@pytest.mark.parametrize("name", DOCUMENTS)
def test_prose_numbers_are_in_referenced_tables(name: str):
    document = ROOT / name
    text = document.read_text()
    prose = readme_prose(text) if document.suffix == ".md" else rst_prose(text)
    known = {number for table in referenced_tables(document, text) for number in numbers(table.read_text())}
    typed = sorted({number for number in numbers(prose) if number not in known})
    assert not typed, f"{name}: numbers in the prose that no referenced table file holds: {typed}"
