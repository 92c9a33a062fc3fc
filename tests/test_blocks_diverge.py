"""A block that is driven beyond its rule's stated stability bound warns once, naming itself and
the bound, before its weights diverge; a learning step missing an argument its rule needs is one
error naming the argument and the block; weights that are no longer finite are named as the cause."""
import warnings

import pytest
import torch

from neuroimagery.nn import AllToAll, Delta, Hebbian, PopulationMap
from neuroimagery.nn.rules import STEP_BOUND


def codes(B=200, seed=0):
    angle = PopulationMap("angle", (37,), low=-90, high=90, sigma=8)
    posture = PopulationMap("posture", (13,), low=-90, high=90, sigma=8)
    a = torch.rand(B, 1, generator=torch.Generator().manual_seed(seed)) * 180 - 90
    return angle.encode(a)[:, 0], posture.encode(a)[:, 0]  # (B, 37), (B, 13): one participant, B trials


def train(conn, x, y, steps=20):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(steps):
            conn.learn(x, conn(x), target=y)
    return [w for w in caught if "gain" in str(w.message)]


def test_summed_delta_on_a_large_batch_warns_once_naming_the_block():
    x, y = codes()
    conn = AllToAll(37, 13, rules=Delta(eta=0.1), name="forward")
    caught = train(conn, x, y)
    assert not torch.isfinite(conn.weight).all() or conn.weight.abs().max() > 1e6  # it does diverge
    assert len(caught) == 1
    msg = str(caught[0].message)
    assert "'forward'" in msg and "Delta" in msg and "batch of 200" in msg and f"above {STEP_BOUND:g}, the bound" in msg
    assert caught[0].filename == __file__  # points at the caller's line


def test_stable_steps_do_not_warn_and_converge():
    x, y = codes()
    conn = AllToAll(37, 13, rules=Delta(eta=0.1, reduction="mean"))
    before = float((conn(x) - y).pow(2).mean())
    assert train(conn, x, y, steps=50) == []
    assert float((conn(x) - y).pow(2).mean()) < before
    one = AllToAll(37, 13, rules=Delta(eta=0.1))  # the online rule: one pattern per step
    assert train(one, x[:1], y[:1]) == []


def test_the_bound_is_the_one_where_steps_start_to_grow():
    # one pattern: the step multiplies its error by 1 - eta |x|^2, so it grows exactly beyond gain 2
    x = torch.ones(1, 4)  # |x|^2 = 4
    for eta, grows in ((0.45, False), (0.55, True)):
        conn = AllToAll(4, 1, init="zeros", rules=Delta(eta=eta))
        errs = []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(5):
                errs.append(float((torch.ones(1, 1) - conn(x)).abs()))
                conn.learn(x, conn(x), target=torch.ones(1, 1))
        assert (errs[-1] > errs[0]) == grows
        assert (len([w for w in caught if "gain" in str(w.message)]) == 1) == grows


def test_hebbian_on_a_large_summed_batch_warns():
    x, y = codes()
    conn = AllToAll(37, 13, rules=Hebbian(eta=0.2), name="c1")
    with pytest.warns(UserWarning, match=r"connection 'c1': a Hebbian step over a batch of 200"):
        conn.learn(x, y)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        AllToAll(37, 13, rules=Hebbian(eta=0.2, reduction="mean")).learn(x, y)


@pytest.mark.parametrize("rule, call, missing", [
    (Delta(0.1), dict(target=torch.rand(3, 2)), "'post'"),
    (Delta(0.1), dict(post=torch.rand(3, 2)), "'target'"),
    (Hebbian(0.1), dict(), "'post'"),
])
def test_a_missing_argument_is_named(rule, call, missing):
    conn = AllToAll(4, 2, rules=rule, name="mine")
    with pytest.raises(ValueError, match=rf"connection 'mine': {type(rule).__name__}.learn needs {missing}"):
        conn.learn(torch.rand(3, 4), **call)


def test_weights_no_longer_finite_are_named():
    conn = AllToAll(4, 2, rules=Delta(0.1), name="mine")
    conn.weight.fill_(float("inf"))
    x = torch.rand(3, 4)
    with pytest.raises(ValueError, match="weights of connection 'mine' are no longer finite"):
        conn.learn(x, conn(x), target=torch.rand(3, 2))


def test_a_sequence_that_diverges_warns_once():
    x = (torch.rand(2000, 30, generator=torch.Generator().manual_seed(1)) > 0.3).float()  # 0/1: the fast form
    y = torch.rand(2000, 5, generator=torch.Generator().manual_seed(2))
    conn = AllToAll(30, 5, rules=Delta(eta=0.5), name="seq")
    with pytest.warns(UserWarning, match="connection 'seq': its weights are no longer finite"):
        conn.learn(x, None, sequence=True, batch=50, target=y)


def test_the_readme_block_examples_run_without_warning():
    import pathlib
    import re
    text = (pathlib.Path(__file__).resolve().parents[1] / "README.md").read_text()
    code = "\n".join(re.findall(r"```python\n(.*?)```", text, re.S))
    scope = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exec(compile(code, "README.md", "exec"), scope)
    assert scope["x"].shape == (200, 37) and scope["xs"].shape == (4, 50, 37)
    assert scope["one"](scope["x"]).shape == (200, 13) and scope["four"](scope["xs"]).shape == (4, 50, 13)
