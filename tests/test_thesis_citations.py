"""What users read cites the thesis by section, figure, table and equation numbers (which any copy
of the thesis has), never by line numbers of the plain text the project was built from."""
import re
from pathlib import Path

import pytest

from neuroimagery.core.thesis import EXP1, EXP2, EXP3, EXP4, EXP5_LINES, FIGURES, SECTIONS, figure_caption, section_of

ROOT = Path(__file__).resolve().parents[1]
LINE_CITE = re.compile(r"\b(?:thesis )?(?:lines?|l\.) ?\d{3,4}\b", re.IGNORECASE)


def test_section_of_maps_lines_to_the_thesis_headings():
    assert [section_of(n) for n in (673, 697, 713, 714, 857, 1043, 1248, 1699)] == [
        "section 5.1.2", "section 5.1.2", "section 5.1.2", "section 5.1.3", "section 5.2.2", "section 6.1.2",
        "section 6.2.3", "section 7.1.3"]
    assert [start for start, _ in SECTIONS] == sorted(start for start, _ in SECTIONS)
    with pytest.raises(ValueError):
        section_of(100)


def test_every_caption_cites_a_section_and_no_line():
    for i, stem in enumerate(FIGURES, 1):
        c = figure_caption(stem, i)
        assert re.search(r"\(section [5-8](\.\d+)*\)\.$", c), c
        assert not LINE_CITE.search(c), c
    for t in [*EXP1.values(), *EXP2.values(), *EXP3.values(), *EXP4.values()]:
        assert section_of(t.line).startswith("section ")
    assert all(section_of(n) for n in EXP5_LINES.values())


def test_checker_catches_line_citations():
    assert LINE_CITE.search("Thesis: 79 % (line 1248).") and LINE_CITE.search("thesis lines 905-915")
    assert LINE_CITE.search("Line 1532 reinitialises the DMP")
    assert not LINE_CITE.search("the line of sight; lines of 20 rotation steps; section 6.2.3, Fig. 6.9c")


def test_user_docs_and_report_text_cite_no_thesis_lines():
    """README, docs/ and the strings the experiments and analysis write into reports."""
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
             *sorted((ROOT / "neuroimagery" / "experiments").glob("*.py")),
             *sorted((ROOT / "neuroimagery" / "analysis").glob("*.py"))]
    found = [f"{p.relative_to(ROOT)}:{n}: {line.strip()}" for p in files
             for n, line in enumerate(p.read_text().splitlines(), 1) if LINE_CITE.search(line)]
    assert found == []
