"""Every ```python block of the README and of the documentation book runs, and prints what
its page says it prints (the convention of tests/doc_programs.rs: a block followed by a
paragraph ending in "prints:" and a ```text block; each non-empty line of that block must
appear in the output). A block whose first line is a comment starting with "fragment" is
not run. Programs run in the repository root."""

import re
import subprocess
import sys

import pytest

from conftest import ROOT

FENCE = re.compile(r"^(\s*)```(\w*)[^\n]*\n(.*?)^\1```\s*$", re.M | re.S)


def pages():
    return [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))


def programs():
    """(place, code, expected lines) of every python program of the pages."""
    found = []
    for page in pages():
        text = page.read_text()
        blocks = [(m.start(), m.end(), m.group(2), m.group(3)) for m in FENCE.finditer(text)]
        for k, (start, _, lang, code) in enumerate(blocks):
            if lang != "python" or re.match(r"\s*#\s*fragment", code):
                continue
            expected = []
            if k + 1 < len(blocks):
                nstart, _, nlang, ncode = blocks[k + 1]
                between = text[blocks[k][1] : nstart].strip().lower()
                if nlang == "text" and between.endswith("prints:"):
                    expected = [line.strip() for line in ncode.splitlines() if line.strip()]
            line = text.count("\n", 0, start) + 1
            found.append((f"{page.relative_to(ROOT)}:{line}", code, expected))
    return found


def test_the_readme_and_the_book_have_python_programs():
    places = [p for p, _, expected in programs() if expected]
    assert any(p.startswith("README.md") for p in places), "README.md: no python program with stated output"
    assert any(p.startswith("docs/python.md") for p in places), "docs/python.md: no python program with stated output"


@pytest.mark.parametrize("place, code, expected", programs(), ids=[p for p, _, _ in programs()])
def test_program_runs_and_prints_what_its_page_says(place, code, expected):
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"{place}:\n{done.stderr}"
    for line in expected:
        assert line in done.stdout, f"{place}: {line!r} not in the output:\n{done.stdout}"
