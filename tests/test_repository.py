"""Checks of the tracked tree itself: no file keeps the markers of an unresolved merge."""
import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# a merge leaves "<<<<<<< ours", "=======" and ">>>>>>> theirs" at the start of lines; the first
# and last are searched for (a line of "=" alone is also a Markdown heading underline)
MARKER = re.compile(rb"^(<{7} |>{7} )", re.MULTILINE)
SKIP_DIRS = {".git", ".venv", "outputs", "multirun", ".pytest_cache", "__pycache__"}


def tracked_files(root: Path) -> list[Path]:
    """The files git tracks under ``root``, or every file outside the build and run folders when
    ``root`` is not a git checkout (e.g. an unpacked source archive)."""
    try:
        out = subprocess.run(["git", "-C", str(root), "ls-files", "-z"], capture_output=True, check=True).stdout
        return [root / p for p in out.decode().split("\0") if p]
    except (OSError, subprocess.CalledProcessError):
        return [p for p in root.rglob("*") if p.is_file() and not SKIP_DIRS.intersection(p.relative_to(root).parts)]


def conflict_markers(files) -> list[str]:
    """``path:line: text`` of every merge-conflict marker line in ``files``."""
    found = []
    for path in files:
        try:
            data = path.read_bytes()
        except OSError:  # a tracked file deleted in the work tree, a broken link
            continue
        for m in MARKER.finditer(data):
            line = data.count(b"\n", 0, m.start()) + 1
            text = data[m.start(): data.find(b"\n", m.start())].decode(errors="replace")
            found.append(f"{path}:{line}: {text}")
    return found


def test_checker_finds_markers(tmp_path):
    clean = tmp_path / "clean.md"
    clean.write_text("Title\n=======\n\ntext with <<<<<<< inside a line\n")
    bad = tmp_path / "bad.md"
    bad.write_text("a\n<<<<<<< HEAD\nours\n=======\ntheirs\n>>>>>>> 4315852\n")
    assert conflict_markers([clean]) == []
    assert [f.split(":", 1)[1] for f in conflict_markers([bad])] == ["2: <<<<<<< HEAD", "6: >>>>>>> 4315852"]


def test_no_merge_conflict_markers_in_tracked_files():
    files = tracked_files(ROOT)
    assert len(files) > 50, "the tracked tree was not read"
    assert conflict_markers(files) == []


def test_citation_files_name_the_thesis_and_the_package():
    import yaml

    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    thesis = cff["references"][0]
    assert thesis["type"] == "thesis" and thesis["title"] == "Mental Imagery in Humanoid Robots"
    assert cff["version"] == __import__("tomllib").loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    readme = (ROOT / "README.md").read_text()
    bib = readme.split("```bibtex\n", 1)[1].split("```", 1)[0]
    entries = re.findall(r"@(\w+)\{([^,]+),", bib)
    assert entries == [("phdthesis", "seepanomwan_mental_imagery"), ("software", "neuroimagery")]
    assert bib.count("{") == bib.count("}")
    assert f"version = {{{cff['version']}}}" in bib


def test_architecture_lists_every_file_of_the_package():
    """docs/architecture.md names every module (by its path below ``neuroimagery/`` where two
    modules share a file name), so the map of the layers stays the map of the code."""
    doc = (ROOT / "docs" / "architecture.md").read_text()
    files = [p.relative_to(ROOT / "neuroimagery") for p in (ROOT / "neuroimagery").rglob("*.py")
             if p.name != "__init__.py" and "__pycache__" not in p.parts]
    names = [p.name for p in files]
    missing = [str(p) for p in files
               if f"`{p.as_posix()}`" not in doc and f"`neuroimagery/{p.as_posix()}`" not in doc
               and f"`{p.parent.name}/{p.name}`" not in doc
               and (names.count(p.name) > 1 or f"`{p.name}`" not in doc)]
    assert missing == []


def test_architecture_names_only_files_and_modules_that_exist():
    """Every package file (``nn/som.py``, ``neuroimagery/app/run.py``) and dotted module
    (``neuroimagery.app.pool``) docs/architecture.md names exists, so the map never names code that
    is gone."""
    doc = (ROOT / "docs" / "architecture.md").read_text()
    pkg = ROOT / "neuroimagery"
    known = {p.relative_to(pkg).as_posix() for p in pkg.rglob("*.py")}
    stale = []
    for ref in re.findall(r"`((?:neuroimagery/)?[a-z_0-9]+(?:/[a-z_0-9]+)*\.py)`", doc):
        rel = ref.removeprefix("neuroimagery/")
        if "/" in rel and not any(k == rel or k.endswith("/" + rel) for k in known) and not (ROOT / ref).is_file():
            stale.append(ref)
    for ref in re.findall(r"\bneuroimagery(?:\.[a-z_0-9]+)+", doc):
        parts = ref.split(".")[1:]
        # a module, or a name inside one: the longest prefix that is a module or package must exist
        if not any((pkg.joinpath(*parts[:k]).with_suffix(".py")).is_file() or (pkg.joinpath(*parts[:k]) / "__init__.py").is_file()
                   for k in range(len(parts), 0, -1)):
            stale.append(ref)
    assert stale == []
