"""The Markdown check every report passes (``report.md`` of a run, of a user's stimulus folder, of
a pool): parsed by Python-Markdown (with its tables extension, as TensorBoard's text plugin and
most renderers read it), every table has as many cells in each row as in its header, no list item
is empty or ends in a bare colon, no p value is printed as 0, and every embedded figure exists."""
from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

import markdown

_P_ZERO = re.compile(r"\bp(?: \([^)]*\))?\s*[=:]\s*0(?:\.0*)?(?![\d.eE])")


def _cells(line: str) -> list[str]:
    """The cells of a table row as GitHub-flavoured Markdown splits it: on pipes that are neither
    escaped nor inside a code span."""
    out, cur, code, i = [], "", False, 0
    s = line.strip()
    if s.startswith("|"):
        s = s[1:]
    if s.endswith("|") and not s.endswith("\\|"):
        s = s[:-1]
    while i < len(s):
        ch = s[i]
        if ch == "\\" and i + 1 < len(s):
            cur += s[i:i + 2]
            i += 2
            continue
        if ch == "`":
            code = not code
        if ch == "|" and not code:
            out.append(cur.strip())
            cur = ""
        else:
            cur += ch
        i += 1
    out.append(cur.strip())
    return out


class _Html(HTMLParser):
    """Tables (rows of cell texts, header first), list items and images of rendered HTML."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[list[list[str]]] = []
        self.items: list[str] = []
        self.images: list[str] = []
        self._cell: list[str] | None = None
        self._li: list[list[str]] = []

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "li":
            self._li.append([])
        elif tag == "img":
            self.images.append(dict(attrs).get("src", ""))

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][-1].append("".join(self._cell).strip())
            self._cell = None
        elif tag == "li" and self._li:
            self.items.append("".join(self._li.pop()).strip())

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)
        for li in self._li:
            li.append(data)


def markdown_problems(text: str, root: Path | None = None) -> list[str]:
    """What keeps ``text`` from rendering as its author meant; empty when it passes."""
    problems = []
    lines = text.splitlines()
    # tables in the source: a header row, a delimiter row, then rows, all with the header's cell count
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and line.lstrip().startswith("|") and re.fullmatch(r"\s*\|?(\s*:?-{3,}:?\s*\|)+\s*:?-*:?\s*\|?\s*", lines[i + 1]):
            n = len(_cells(line))
            if len(_cells(lines[i + 1])) != n:
                problems.append(f"line {i + 2}: delimiter row of {len(_cells(lines[i + 1]))} cells under a header of {n}")
            k = i + 2
            while k < len(lines) and lines[k].lstrip().startswith("|"):
                if len(_cells(lines[k])) != n:
                    problems.append(f"line {k + 1}: {len(_cells(lines[k]))} cells under a header of {n}: {lines[k][:80]}")
                k += 1
    html = markdown.markdown(text, extensions=["tables"])
    doc = _Html()
    doc.feed(html)
    n_src = sum(1 for i, ln in enumerate(lines[:-1]) if ln.lstrip().startswith("|") and set(lines[i + 1].strip()) <= set("|-: ")
                and "-" in lines[i + 1])
    if len(doc.tables) != n_src:
        problems.append(f"{n_src} tables written, {len(doc.tables)} rendered")
    for t, rows in enumerate(doc.tables, 1):
        head = rows[0] if rows else []
        pcols = [j for j, h in enumerate(head) if re.fullmatch(r"(.* )?p( \(.*\))?", h)]
        for r in rows[1:]:
            if len(r) != len(head):
                problems.append(f"table {t}: a rendered row of {len(r)} cells under {len(head)}")
            for j in pcols:
                if j < len(r) and re.fullmatch(r"0(\.0*)?", r[j]):
                    problems.append(f"table {t}: p printed as {r[j]!r} in column {head[j]!r}")
    for item in doc.items:
        if not item or item.endswith(":"):
            problems.append(f"empty list item {item!r}")
    for m in _P_ZERO.finditer(re.sub(r"<[^>]+>", "", html)):
        problems.append(f"p printed as 0: {m.group(0)!r}")
    if root is not None:
        for src in doc.images:
            if not (root / src).is_file():
                problems.append(f"figure {src} does not exist")
    return problems


def check_report(path: Path) -> None:
    """Assert that the report at ``path`` passes :func:`markdown_problems`."""
    path = Path(path)
    problems = markdown_problems(path.read_text(), path.parent)
    assert not problems, f"{path} does not render:\n  " + "\n  ".join(problems)
