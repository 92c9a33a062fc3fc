"""The registered forms of a rule over a sequence (nn/forms.py, nn/learning.py) against the plain
step-by-step rule: same weights within a stated float tolerance, same discrete outcomes (the
winning output unit of every training input), and the choice made from the inputs."""
import pytest
import torch

from neuroimagery.nn import AllToAll, Delta, Hebbian
from neuroimagery.nn import forms
from neuroimagery.nn.learning import IndexedRows

# float32 weights formed by another summation order (closed form in float64 or float32, sparse
# column sums): a few ulps of the O(1) weights, far below any difference a learning step makes
ATOL = 1e-5


def _pair(n_in, n_out, rule, P=3, seed=4):
    a = AllToAll(n_in, n_out, participants=P, seed=seed, rules=rule)
    b = AllToAll(n_in, n_out, participants=P, seed=seed, rules=rule)
    return a, b


def _same_outcomes(a, b, x):
    assert torch.equal(a.net(x).argmax(-1), b.net(x).argmax(-1))


def test_shared_outstar_sequence_equals_the_plain_rule():
    g = torch.Generator().manual_seed(0)
    pre, post = torch.rand(40, 12, generator=g), torch.rand(40, 7, generator=g)
    a, b = _pair(12, 7, Hebbian(0.2))
    a.learn(pre, post, sequence=True)
    b.learn(pre, post, sequence=True, method="plain")
    assert a.learnt_factors["kind"] == "hebbian_shared" and b.learnt_factors is None
    assert not torch.equal(b.weight, AllToAll(12, 7, participants=3, seed=4).weight)
    assert torch.allclose(a.weight, b.weight, atol=ATOL)
    _same_outcomes(a, b, pre.expand(3, -1, -1))


@pytest.mark.parametrize("per_participant_pre", [False, True])
def test_indexed_outstar_sequence_equals_the_plain_rule(per_participant_pre):
    g = torch.Generator().manual_seed(1)
    P, T, K = 3, 50, 5
    table_in = torch.rand(P, 6, 10, generator=g) if per_participant_pre else torch.rand(6, 10, generator=g)
    pre = IndexedRows(table_in, torch.randint(6, (P, T), generator=g))
    post = IndexedRows(torch.rand(K, 8, generator=g), torch.randint(K, (P, T), generator=g))
    a, b = _pair(10, 8, Hebbian(0.3), P)
    a.learn(pre, post, sequence=True)
    b.learn(pre, post, sequence=True, method="plain")
    assert a.learnt_factors["kind"] == "hebbian_indexed"
    assert torch.allclose(a.weight, b.weight, atol=ATOL)
    _same_outcomes(a, b, pre.rows(0, T))


@pytest.mark.parametrize("flush", [False, True])
def test_compiled_suffix_products_are_torchs_cumulative_products(flush):
    """The closed forms' decay products (compiled when numba is installed) are the bits of
    ``torch.cumprod`` from the last step back, with and without subnormals flushed, also where
    the running products underflow."""
    from neuroimagery.nn.hebbian_closed_form import suffix_products
    from neuroimagery.nn.numerics import flush_subnormals

    g = torch.Generator().manual_seed(5)
    keep = 1 - 0.3 * torch.cat([torch.rand(600, 40, generator=g), (torch.rand(600, 30, generator=g) > 0.5).float()], 1)
    with flush_subnormals(flush):
        suffix, whole = suffix_products(keep)
        rev = torch.cumprod(torch.flip(keep, [0]), 0)
        ref = torch.cat([torch.flip(rev, [0])[1:], torch.ones(1, 70)], 0)
    assert torch.equal(suffix, ref) and torch.equal(whole, rev[-1])
    assert (whole == 0).any() and (suffix[-100] > 0).all()  # products that underflow, and ones that do not yet


def test_binary_delta_minibatches_equal_the_plain_rule():
    g = torch.Generator().manual_seed(2)
    X = (torch.rand(2, 30, 16, generator=g) > 0.7).float()
    Y = torch.rand(2, 30, 9, generator=g)
    a, b = _pair(16, 9, Delta(0.1), P=2)
    a.learn(X, None, sequence=True, batch=4, target=Y)  # auto: 0/1 inputs on the CPU -> the sparse kernel
    b.learn(X, None, sequence=True, batch=4, target=Y, method="plain")
    c = AllToAll(16, 9, participants=2, seed=4, rules=Delta(0.1))
    c.learn(X, None, sequence=True, batch=4, target=Y, method="delta_binary")
    assert torch.equal(a.weight, c.weight)  # auto chose the binary kernel
    assert torch.allclose(a.weight, b.weight, atol=ATOL)
    _same_outcomes(a, b, X)


def test_kernels_are_chosen_from_the_inputs_and_refused_when_they_do_not_apply():
    g = torch.Generator().manual_seed(3)
    X = torch.rand(2, 10, 6, generator=g)  # not binary: the plain rule
    Y = torch.rand(2, 10, 4, generator=g)
    a, b = _pair(6, 4, Delta(0.1), P=2)
    a.learn(X, None, sequence=True, batch=3, target=Y)
    for s in range(0, 10, 3):  # the plain form by hand: one learn step per mini-batch, at the current weights
        x = X[:, s:s + 3]
        b.learn(x, b(x), target=Y[:, s:s + 3])
    assert torch.equal(a.weight, b.weight)
    with pytest.raises(ValueError, match="does not apply"):
        a.learn(X, None, sequence=True, target=Y, method="delta_binary")
    h = AllToAll(6, 4, participants=2, rules=Hebbian(0.1))
    with pytest.raises(ValueError, match="does not apply"):  # batches of several patterns are not the online sequence
        h.learn(X[0], Y[0], sequence=True, batch=2, method="hebbian_shared")
    with pytest.raises(ValueError, match="method must be"):
        h.learn(X[0], Y[0], sequence=True, method="fast")
    assert set(forms.names(h)) >= {"plain", "hebbian_shared", "hebbian_indexed", "delta_binary"}


def test_a_sequence_in_eval_mode_changes_nothing():
    a = AllToAll(5, 3, participants=1, rules=Hebbian(0.5)).eval()
    w = a.weight.clone()
    with pytest.warns(UserWarning, match=r"eval\(\) mode"):
        a.learn(torch.rand(4, 5), torch.rand(4, 3), sequence=True)
    assert torch.equal(a.weight, w)
