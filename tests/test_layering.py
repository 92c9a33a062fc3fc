"""Data flow one way: blocks (nn/, motor/, vision/, robot/) -> models/ -> experiments/ -> the entry
points above them. Every import of every source file is read (those inside functions too)."""
import ast
from pathlib import Path

import neuroimagery

ROOT = Path(neuroimagery.__file__).parent
BLOCKS = ("nn", "motor", "vision", "robot")
# what each layer may not import
FORBIDDEN = {**{b: ("models", "experiments", "run", "config", "pool", "cli") for b in BLOCKS},
             "models": ("experiments", "run", "config", "pool", "cli")}


def _imports(path: Path, root: Path = ROOT) -> list[tuple[int, str]]:
    """Every module ``path`` imports, as a dotted name inside the package (``nn.som``, ``experiments``)."""
    pkg = path.relative_to(root).with_suffix("").parts[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(pkg[: len(pkg) - node.level + 1])
                mod = ".".join(base + ([node.module] if node.module else []))
                names = [mod] if node.module else [".".join(base + [a.name]) for a in node.names]
            elif node.module and node.module.startswith("neuroimagery"):
                names = [node.module[len("neuroimagery."):] if "." in node.module else ""]
            else:
                continue
            out += [(node.lineno, n) for n in names]
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name[len("neuroimagery."):]) for a in node.names if a.name.startswith("neuroimagery.")]
    return out


def _violations(layer: str) -> list[str]:
    bad = []
    for path in sorted((ROOT / layer).rglob("*.py")):
        for line, mod in _imports(path):
            top = mod.split(".")[0]
            if top in FORBIDDEN[layer]:
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {mod}")
    return bad


def test_blocks_know_no_model_or_experiment():
    assert [v for b in BLOCKS for v in _violations(b)] == []


def test_models_know_no_experiment():
    assert _violations("models") == []


# Experiment 5's modules are checked once their own split lands
PRIVATE_IMPORT_EXEMPT = {"experiments/exp5_pool.py"}


def test_no_module_imports_a_private_name_of_another():
    bad = []
    for path in sorted(p for p in ROOT.rglob("*.py") if str(p.relative_to(ROOT)) not in PRIVATE_IMPORT_EXEMPT):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("neuroimagery")):
                bad += [f"{path.relative_to(ROOT)}:{node.lineno} imports {a.name}" for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
    assert bad == []


def test_the_import_reader_sees_relative_and_lazy_imports(tmp_path):
    """The check itself: a relative import inside a function of a block is resolved and caught."""
    (tmp_path / "nn").mkdir()
    f = tmp_path / "nn" / "x.py"
    f.write_text("import torch\nfrom .rules import Hebbian\n\ndef f():\n    from ..experiments import exp4\n"
                 "    from neuroimagery.models.rotation_motor import RowCache\n")
    assert [m for _, m in _imports(f, tmp_path)] == ["nn.rules", "experiments", "models.rotation_motor"]
