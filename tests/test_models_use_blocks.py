"""The thesis's models run on the blocks: no module of ``neuroimagery/models`` reads or writes a
connection's or a map's weights itself (``.weight``); every product and every learning step goes
through the blocks' own methods (``net``, ``forward``, ``learn``, ``fit``, ...). Checkpoints save
and load the blocks through their ``state_dict``."""
from __future__ import annotations

import ast
from pathlib import Path

MODELS = Path(__file__).resolve().parents[1] / "neuroimagery" / "models"


def weight_accesses(source: str) -> list[int]:
    """Line numbers of every ``<expr>.weight`` attribute (read, write or delete) in ``source``."""
    return sorted(node.lineno for node in ast.walk(ast.parse(source))
                  if isinstance(node, ast.Attribute) and node.attr == "weight")


def test_the_check_sees_reads_and_writes():
    src = "a = conn.weight[0] @ x\nconn.weight.zero_()\nm.c3.som.weight = w\nb = conn.net(x)\nw = getattr(c, 'weights')\n"
    assert weight_accesses(src) == [1, 2, 3]


def test_no_model_touches_a_blocks_weights():
    files = sorted(MODELS.rglob("*.py"))
    assert len(files) > 10  # the models are where the test looks
    found = [f"{f.relative_to(MODELS.parent.parent)}:{line}" for f in files
             for line in weight_accesses(f.read_text())]
    assert not found, "models read or write a block's .weight (use the block's methods): " + ", ".join(found)
