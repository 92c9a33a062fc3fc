"""One learning contract: a rule computes the change at the given weights without touching them
(``rule.delta(weight, pre=..., **activity) -> Change``) and the learner that owns the weights (a
connection, a SOM) applies it; the forms of the rules are registered where they are defined and
the registry loads those modules itself."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest
import torch

from neuroimagery.nn import (SOM, AllToAll, Delta, GatedHebbian, Hebbian, Kohonen, QLearning, Sanger,
                             SupervisedKohonen, forms)
from neuroimagery.nn.change import Change
from neuroimagery.nn.rules import Rule

NN = Path(__file__).resolve().parents[1] / "neuroimagery" / "nn"


def _cases():
    g = torch.Generator().manual_seed(3)
    x = (torch.rand(2, 1, 6, generator=g) < 0.5).float()
    y = torch.rand(2, 1, 4, generator=g)
    grid = torch.arange(4.0).unsqueeze(1)
    return [
        (Hebbian(0.1), dict(pre=x, post=y)),
        (Hebbian(0.1, "instar", reduction="mean"), dict(pre=x, post=y)),
        (Delta(0.1), dict(pre=x, post=y, target=torch.rand(2, 1, 4, generator=g))),
        (GatedHebbian(0.2), dict(pre=x, post=y, gate=torch.tensor([[0.0, 1.0, 0.0, 1.0], [1.0, 0, 0, 0]]), repeats=3)),
        (QLearning(0.1), dict(pre=x, action=torch.tensor([[1], [3]]), reward=torch.tensor([[1.0], [0.0]]),
                              next_pre=x.flip(-1))),
        (Sanger(0.1), dict(pre=torch.rand(2, 3, 6, generator=g))),
        (Kohonen(0.5, 1.0), dict(pre=x, bmu=torch.tensor([1, 2]), grid=grid)),
        (SupervisedKohonen(0.5, 1.0), dict(pre=x, bmu=torch.tensor([1, 2]), grid=grid)),
    ]


@pytest.mark.parametrize("rule, activity", _cases(), ids=lambda v: type(v).__name__ if isinstance(v, Rule) else "")
def test_a_rule_computes_a_change_and_leaves_the_weights_alone(rule, activity):
    w = torch.rand(2, 4, 6, generator=torch.Generator().manual_seed(1))
    before = w.clone()
    change = rule.delta(w, **activity)
    assert isinstance(change, Change)
    assert torch.equal(w, before)  # computing the change wrote nothing
    dense = change.tensor()
    assert dense.shape == w.shape and torch.equal(w, before)
    change.apply_(w)  # what the learner does
    assert torch.allclose(w, before + dense, atol=1e-6)


@pytest.mark.parametrize("rule, activity", _cases()[:6], ids=lambda v: type(v).__name__ if isinstance(v, Rule) else "")
def test_a_connection_applies_its_rules_change(rule, activity):
    c = AllToAll(6, 4, participants=2, rules=rule)
    w0 = c.weight.clone()
    want = w0 + rule.delta(w0.clone(), **activity)
    c.learn(**activity)
    assert torch.allclose(c.weight, want, atol=1e-6)


def test_no_rule_writes_weights_itself():
    for cls in (Hebbian, GatedHebbian, Delta, QLearning, Sanger, Kohonen, SupervisedKohonen):
        assert not hasattr(cls, "apply_"), cls


def test_a_som_applies_its_rules_change_and_honours_a_rule_that_overrides_delta():
    class Half(Kohonen):
        def delta(self, weight, **kw):
            return 0.5 * super().delta(weight, **kw)

    a = SOM((4,), 6, participants=2, seed=0, eta=0.5, sigma=1.0)
    b = SOM((4,), 6, participants=2, seed=0, eta=0.5, sigma=1.0)
    b.rule = Half(0.5, 1.0, a.rule.iterations, a.rule.eta1, a.rule.sigma1)
    x = torch.rand(2, 6, generator=torch.Generator().manual_seed(2))
    w0 = a.weight.clone()
    win = a.step(x)
    b.step(x, win)
    full = a.weight - w0
    assert full.abs().sum() > 0
    assert torch.allclose(b.weight - w0, 0.5 * full, atol=1e-6)


def _modules_that_register() -> set[str]:
    out = set()
    for path in NN.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and any(
                    isinstance(d, ast.Call) and getattr(d.func, "id", "") == "register" for d in node.decorator_list):
                out.add(path.stem)
    return out


def test_the_registry_names_every_module_that_defines_forms():
    found = _modules_that_register()
    assert {"connections", "delta", "som_online"} <= found  # the scan sees the decorators
    assert found == set(forms.DEFINED_IN)


def test_the_package_does_not_import_modules_for_their_registrations():
    init = (NN / "__init__.py").read_text()
    assert "register" not in init.split('"""')[-1]
    assert "noqa: F401" not in init
