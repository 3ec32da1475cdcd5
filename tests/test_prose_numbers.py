"""Every measured number in the README's prose and in docs/ comes from a result file.

The rule: a section of a page (a heading and the text up to the next heading) names the files its
numbers come from: ``results/...`` files and executed notebooks, globs allowed
(``anseg/study/reference.py`` for the paper's own figures). A folder it names is a pointer for
the reader, not a source.
Every decimal number in the section, outside code spans and the generated blocks, must equal a
value stored in one of those files, rounded to the digits shown, read either as it is or as a
percentage (0.9205 is shown as 92.05). A number a section cannot source is a finding: store it,
name its file, or leave it out.

Why per section and not per page: a folder of 400 run records holds so many values that most
two-decimal numbers would match by chance. So the test also checks its own power: the files a
section names must miss at least 80 % of a grid of made-up two-decimal numbers, or the section
must name narrower files. Integers are counts, sizes and settings, and are not checked.
"""

from __future__ import annotations

import glob
import re
from functools import lru_cache
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]

GENERATED = re.compile(r"<!-- (headline|ledger):.*?<!-- /\1 -->", re.S)
CODE = re.compile(r"```.*?```|`[^`\n]*`", re.S)
SOURCE = re.compile(r"(?:results|notebooks/executed)/[\w./*\-]*|anseg/study/reference\.py")
SHOWN = re.compile(r"(?<![\w.])[-+−]?(\d+\.\d+)(?![\w.]*\d)")
STORED = re.compile(r"-?\d+\.\d+(?:[eE]-?\d+)?")
TEXT_SUFFIXES = {".csv", ".json", ".txt", ".py", ".ipynb"}
MADE_UP = [f"{0.37 * k + 0.01:.2f}" for k in range(270)]  # 0.01 .. 99.91, a grid no measurement picked
MOST_CHANCE = 0.2


def sections(text: str) -> list[tuple[str, str]]:
    """(heading, text) for every section of a page, with generated blocks left out."""
    parts = re.split(r"\n(?=#{1,6} )", "\n" + GENERATED.sub("", text))
    return [(part.strip().splitlines()[0], part) for part in parts if part.strip()]


def shown_numbers(text: str) -> list[str]:
    """The decimal numbers a reader sees in ``text``, code spans and blocks left out, sign dropped."""
    return [m.group(1) for m in SHOWN.finditer(CODE.sub("", text))]


def named_files(text: str, root: Path = REPO) -> set[Path]:
    """The result files a text names, as files or globs; a folder is a pointer for the reader, not a source."""
    files: set[Path] = set()
    for name in SOURCE.findall(text):
        for hit in glob.glob(str(root / name.rstrip("."))):
            path = Path(hit)
            if path.is_file() and path.suffix in TEXT_SUFFIXES:
                files.add(path)
    return files


@lru_cache(maxsize=None)
def readings(path: Path) -> frozenset[str]:
    """Every way a value stored in ``path`` may be shown: as written, or rounded to 1-4 digits, as is or x100."""
    shown = set()
    for match in STORED.finditer(path.read_text(errors="ignore")):
        value = abs(float(match.group()))
        shown.add(match.group().lstrip("-"))
        for scaled in (value, 100 * value):
            shown.update(f"{scaled:.{digits}f}" for digits in range(1, 5))
    return frozenset(shown)


def pool(files: set[Path]) -> set[str]:
    out: set[str] = set()
    for path in files:
        out |= readings(path)
    return out


def findings(text: str, root: Path = REPO) -> list[str]:
    """What the rule finds on one page: unsourced numbers, and sources too broad to tell."""
    out = []
    for heading, body in sections(text):
        numbers = shown_numbers(body)
        if not numbers:
            continue
        files = named_files(body, root)
        found = pool(files)
        chance = sum(n in found for n in MADE_UP) / len(MADE_UP)
        if chance > MOST_CHANCE:
            out.append(f"{heading!r}: its sources match {chance:.0%} of made-up numbers; name narrower files")
        missing = [n for n in numbers if n not in found]
        if missing:
            out.append(f"{heading!r}: {', '.join(missing)} in none of {len(files)} named file(s)")
    return out


def test_numbers_are_read_as_shown_and_checked_against_their_sections_files(tmp_path):
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "t.csv").write_text("category,acc,diff\nHand,0.92054,-1.2449\n")
    assert shown_numbers("a `0.50` setting, 1.25x, v1.2.3 and −3.10") == ["1.25", "3.10"]
    page = "# T\n## A\nHand: 92.05, +1.24 and 0.9205 (`results/t.csv`).\n## B\nHand: 92.05.\n"
    assert findings(page, tmp_path) == ["'## B': 92.05 in none of 0 named file(s)"]
    assert findings("## C\n12.34 (`results/t.csv`)\n", tmp_path) == ["'## C': 12.34 in none of 1 named file(s)"]


def test_a_section_whose_sources_would_match_anything_is_a_finding(tmp_path):
    (tmp_path / "results" / "runs").mkdir(parents=True)
    (tmp_path / "results" / "runs" / "all.csv").write_text("\n".join(f"{k / 100:.2f}" for k in range(10000)))
    assert findings("## D\n42.42 (`results/runs/`)\n", tmp_path) == ["'## D': 42.42 in none of 0 named file(s)"]
    assert findings("## D\n42.42 (`results/runs/*.csv`)\n", tmp_path) == [
        "'## D': its sources match 100% of made-up numbers; name narrower files"]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_number_on_the_page_comes_from_a_file_its_section_names(page):
    if not (REPO / "results" / "table1_psb.csv").is_file():
        pytest.skip("no real-run results committed (results/table1_psb.csv)")
    found = findings(page.read_text())
    assert not found, "\n".join(found)
