"""Data flow one way: base modules -> blocks (nn/, motor/, vision/, robot/) -> models/ -> analysis/
-> config and validation -> experiments/ -> the entry points. The import graph of the package (and
of the repository's ``train.py`` and ``evaluate.py``) is read from the source: every import of
every file counts, those inside functions too; only imports under ``if TYPE_CHECKING:`` are left
out (they never run)."""
import ast
import functools
import re
from pathlib import Path

import neuroimagery

ROOT = Path(neuroimagery.__file__).parent
REPO = ROOT.parent
ENTRY_SCRIPTS = ("train.py", "evaluate.py")  # the repository's entry points beside the package

# The layer of every top-level module and package of neuroimagery/ (a module may import from its
# own layer and the layers below, never from above). A new top-level module must be placed here.
BASE, BLOCKS, MODELS, ANALYSIS, CONFIG, EXPERIMENTS, ENTRY = range(7)
LAYER_NAMES = ("base", "blocks", "models", "analysis", "config", "experiments", "entry points")
LAYERS = {
    # base: what any layer may use; knows no block, model or experiment
    "": BASE,  # the package's __init__
    "core": BASE,  # errors, console, files, threads, locks, manifests, bounds, resources, progress, ...
    # blocks: maps, connections, rules, motor primitives, eyes, the robot world
    "nn": BLOCKS, "motor": BLOCKS, "vision": BLOCKS, "robot": BLOCKS,
    "models": MODELS,  # the thesis's models, built from blocks
    "analysis": ANALYSIS,  # summaries, effects, figures and reports of trial tables
    "config": CONFIG,  # the Hydra schema of a run and its validation
    "validation": CONFIG,  # the checks of a whole configuration before any work
    "experiments": EXPERIMENTS,  # protocols: train, test, summarise, report
    "app": ENTRY,  # run directories, train() and evaluate(), the command line, pooling, the stimulus tool
    **{s: ENTRY for s in ENTRY_SCRIPTS},
}



def _module_name(path: Path, root: Path) -> str:
    if path.parent == root.parent and root.name == "neuroimagery":  # train.py, evaluate.py
        return path.name
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _type_only(node: ast.AST) -> bool:
    t = node.test if isinstance(node, ast.If) else None
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (isinstance(t, ast.Attribute)
                                                                    and t.attr == "TYPE_CHECKING")


def _import_statements(body: list[ast.stmt]):
    """The import statements of ``body`` and of every block nested in it (functions, classes, ``if``,
    ``try``, ``with``, loops), those under ``if TYPE_CHECKING:`` left out (its ``else`` kept)."""
    for stmt in body:
        if isinstance(stmt, (ast.Import, ast.ImportFrom)):
            yield stmt
            continue
        for name in ("body", "orelse", "finalbody", "handlers", "cases"):
            if name == "body" and _type_only(stmt):
                continue
            for child in getattr(stmt, name, None) or []:
                yield from _import_statements(child.body if isinstance(child, (ast.ExceptHandler, ast.match_case))
                                              else [child])


def _imports(path: Path, root: Path = ROOT, modules: set[str] | None = None) -> list[tuple[int, str]]:
    """Every module of the package ``path`` imports, as a dotted name inside it (``nn.som``,
    ``experiments.exp5``; ``from . import x`` names the module ``x`` when there is one, else the
    package), with its line; imports under ``if TYPE_CHECKING:`` left out."""
    script = path.parent == root.parent
    pkg = [] if script else list(path.relative_to(root).with_suffix("").parts[:-1])
    known = modules if modules is not None else _modules(root)
    out = []
    for node in _import_statements(_parse(path).body):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - node.level + 1]
                mod = node.module or ""
            elif node.module and (node.module == "neuroimagery" or node.module.startswith("neuroimagery.")):
                base, mod = [], node.module[len("neuroimagery"):].lstrip(".")
            else:
                continue
            target = ".".join(base + ([mod] if mod else []))
            for a in node.names:
                sub = f"{target}.{a.name}" if target else a.name
                out.append((node.lineno, sub if sub in known else target))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name[len("neuroimagery."):]) for a in node.names
                    if a.name.startswith("neuroimagery.")]
    return out


@functools.lru_cache(maxsize=None)
def _parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text())


def _modules(root: Path = ROOT) -> set[str]:
    return {_module_name(p, root) for p in root.rglob("*.py")}


def _sources(root: Path = ROOT) -> dict[str, Path]:
    out = {_module_name(p, root): p for p in sorted(root.rglob("*.py"))}
    if root == ROOT:
        out.update({s: REPO / s for s in ENTRY_SCRIPTS if (REPO / s).is_file()})
    return out


@functools.lru_cache(maxsize=None)
def import_graph(root: Path = ROOT) -> dict[str, dict[str, int]]:
    """``{module: {imported module: line}}`` of the package's modules (and the entry scripts)."""
    sources = _sources(root)
    known = _modules(root)
    graph = {}
    for name, path in sources.items():
        edges: dict[str, int] = {}
        for line, target in _imports(path, root, known):
            if target != name and (target in known or target == ""):
                edges.setdefault(target, line)
        graph[name] = edges
    return graph


def cycles(graph: dict[str, dict[str, int]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan), each a set."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def layer_of(module: str) -> int | None:
    return LAYERS.get(module.split(".")[0] if module not in LAYERS else module)


def upward_imports(graph: dict[str, dict[str, int]]) -> list[str]:
    bad = []
    for src, edges in sorted(graph.items()):
        for dst, line in sorted(edges.items()):
            a, b = layer_of(src), layer_of(dst)
            if a is not None and b is not None and b > a:
                bad.append(f"{src}:{line} ({LAYER_NAMES[a]}) imports {dst} ({LAYER_NAMES[b]})")
    return bad


# ---------------------------------------------------------------------------------- the tests
def test_every_top_level_module_has_a_layer():
    assert sorted(m for m in _sources() if layer_of(m) is None) == []


def test_the_package_root_holds_at_most_six_modules():
    """The root shows the layers: base utilities in ``core/``, entry points in ``app/``."""
    assert len(list(ROOT.glob("*.py"))) <= 6, sorted(p.name for p in ROOT.glob("*.py"))


def test_no_import_goes_from_a_lower_layer_to_a_higher_one():
    assert upward_imports(import_graph()) == []


def test_no_import_cycle():
    assert [sorted(c) for c in cycles(import_graph())] == []


def test_the_graph_reader_sees_relative_lazy_and_cyclic_imports_and_skips_type_only_ones(tmp_path):
    """The checks themselves, on a small package: a relative import inside a function of a block is
    resolved and caught going up; a cycle is found; an import under TYPE_CHECKING is not an edge."""
    root = tmp_path / "neuroimagery"
    for d in ("nn", "models", "experiments"):
        (root / d).mkdir(parents=True)
        (root / d / "__init__.py").write_text("")
    (root / "__init__.py").write_text("")
    (root / "nn" / "x.py").write_text("import torch\nfrom .rules import Hebbian\n\ndef f():\n"
                                      "    from ..experiments import exp5\n")
    (root / "nn" / "rules.py").write_text("from . import x\n")
    (root / "models" / "m.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                          "    from ..experiments.exp4 import Config\n"
                                          "from neuroimagery.nn.rules import Hebbian\n")
    (root / "experiments" / "exp4.py").write_text("from ..models import m\n")
    (root / "experiments" / "exp5.py").write_text("")
    graph = import_graph(root)
    assert graph["nn.x"] == {"nn.rules": 2, "experiments.exp5": 5}
    assert graph["models.m"] == {"nn.rules": 4}
    assert cycles(graph) == [{"nn.x", "nn.rules"}]
    assert upward_imports(graph) == ["nn.x:5 (blocks) imports experiments.exp5 (experiments)"]


# ------------------------------------------------------------------------ private names, weights
PRIVATE_IMPORT_EXEMPT: set[str] = set()


def test_no_module_imports_a_private_name_of_another():
    bad = []
    for path in sorted(p for p in ROOT.rglob("*.py") if str(p.relative_to(ROOT)) not in PRIVATE_IMPORT_EXEMPT):
        for node in ast.walk(_parse(path)):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("neuroimagery")):
                bad += [f"{path.relative_to(ROOT)}:{node.lineno} imports {a.name}" for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
    assert bad == []


PARTS = re.compile(r"^(fm|c\d+)$")  # a model's banks of connections (forward models, C1 ... C17)


def model_internals(source: str) -> list[tuple[int, str]]:
    """Where ``source`` reaches into a model's parts: reads a ``weight`` or a part's
    ``rules`` / ``grid`` / ``steps``, indexes a bank (``.fm[``, ``.c16[``), calls ``learn`` on
    anything, or ``fit`` / ``fit_*`` on a part (``model.c1.fit(...)``, ``model.fm[0].fit(...)``)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute):
            if node.attr == "weight":
                out.append((node.lineno, ".weight"))
            elif (node.attr in ("rules", "grid", "steps") and isinstance(node.value, ast.Attribute)
                  and isinstance(node.value.value, ast.Name) and node.value.value.id in ("model", "trained")):
                out.append((node.lineno, f".{node.value.attr}.{node.attr}"))
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) and PARTS.match(node.value.attr):
            out.append((node.lineno, f".{node.value.attr}["))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            name, receiver = node.func.attr, node.func.value
            if name == "learn":
                out.append((node.lineno, ".learn("))
            elif (name == "fit" or name.startswith("fit_")) and isinstance(receiver, (ast.Attribute, ast.Subscript)):
                out.append((node.lineno, f"part.{name}("))
    return sorted(out)


def test_experiments_use_a_model_through_its_methods():
    """An experiment trains and reads a model through the model's own methods (``model.fit_*``,
    properties), never through its connections' weights, rules or ``learn``."""
    bad = [f"experiments/{p.name}:{line} {what}" for p in sorted((ROOT / "experiments").glob("*.py"))
           for line, what in model_internals(p.read_text())]
    assert bad == []


def test_the_model_internals_check_catches_each_pattern():
    src = ("for conn in model.fm:\n    conn.learn(x, y)\n"        # 2: learn on anything
           "model.c16[a].fit(x)\n"                                # 3: a bank indexed, fit on a part
           "w = trained.fm[0].K\n"                                # 4
           "v = c.weight[0]\n"                                    # 5
           "model.forward_model.fit_rows(x)\n"                    # 6: fit_* on a part
           "model.fit_confirm(a, b)\nmodel.fit(images)\n"         # the model's own methods: fine
           "res = sm.GLM(y, x).fit()\n"                           # fit on a call's result: fine
           "s = model.som.steps\n")                               # 10
    assert model_internals(src) == [(2, ".learn("), (3, ".c16["), (3, "part.fit("), (4, ".fm["), (5, ".weight"),
                                    (6, "part.fit_rows("), (10, ".som.steps")]


def test_every_import_of_the_package_names_a_module_that_exists():
    """A relative or absolute import of ``neuroimagery`` (those inside functions too) names a module
    or package of the tree, or a name inside one: a module that moved leaves no import behind."""
    known = _modules()
    stale = []
    for name, path in _sources().items():
        for node in _import_statements(_parse(path).body):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                pkg = [] if path.parent == ROOT.parent else list(path.relative_to(ROOT).with_suffix("").parts[:-1])
                target = ".".join(pkg[: len(pkg) - node.level + 1] + ([node.module] if node.module else []))
            elif node.module == "neuroimagery" or (node.module or "").startswith("neuroimagery."):
                target = node.module[len("neuroimagery"):].lstrip(".")
            else:
                continue
            if target not in known:
                stale.append(f"{name}:{node.lineno} imports from {target or 'neuroimagery'}")
    assert stale == []
