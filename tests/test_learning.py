"""The registered forms of a rule over a sequence (nn/forms.py, nn/learning.py) against the plain
step-by-step rule: same weights within a stated float tolerance, same discrete outcomes (the
winning output unit of every training input), and the choice made from the inputs."""
import pytest
import torch

from neuroimagery.nn import AllToAll, Delta, Hebbian
from neuroimagery.nn import forms
from neuroimagery.nn.binary import ActiveRows
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


def test_binary_delta_on_active_units_equals_the_dense_rows():
    """Inputs and targets given by their active units (ActiveRows) train the weights bit for bit
    as their dense 0/1 rows do, with the binary kernel and with the plain rule."""
    g = torch.Generator().manual_seed(6)
    X = (torch.rand(2, 30, 16, generator=g) > 0.7).float()
    Y = (torch.rand(2, 30, 9, generator=g) > 0.6).float()
    X[1, 3] = 0  # an empty pattern
    XA, YA = ActiveRows.of(X), ActiveRows.of(Y)
    assert torch.equal(XA.rows(0, 30), X) and XA.length == 30 and XA.participants == 2
    for method in ("delta_binary", "plain"):
        a, b = _pair(16, 9, Delta(0.05), P=2)
        a.learn(X, None, sequence=True, batch=4, target=Y, method=method)
        b.learn(XA, None, sequence=True, batch=4, target=YA, method=method)
        assert torch.equal(a.weight, b.weight), method
        assert torch.equal(b.transposed(), b.weight.transpose(1, 2).contiguous())  # the trained table kept
    keep = torch.rand(2, 30, generator=g) > 0.5
    sel = XA.select(keep)
    for p in range(2):
        rows = X[p][keep[p]]
        assert torch.equal(sel.rows(0, sel.length)[p, :len(rows)], rows)
        assert not sel.rows(0, sel.length)[p, len(rows):].any()
    with pytest.raises(ValueError, match="ascend"):
        ActiveRows(torch.tensor([[[3, 1]]]), 4)
    with pytest.raises(ValueError, match="0/1"):
        ActiveRows.of(X * 0.5)


def test_tiled_transpose_is_the_transpose():
    from neuroimagery.nn.functional import transposed_copy

    g = torch.Generator().manual_seed(8)
    for shape in ((3, 200, 130), (130, 300), (2, 5, 7)):
        x = torch.rand(shape, generator=g)
        assert torch.equal(transposed_copy(x), x.transpose(-1, -2).contiguous())


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


def test_the_registry_gives_each_learner_the_forms_of_its_rule():
    """One registry: a learner finds the forms of its rule's type and bases, in 'auto' order; a
    local connection owns its forms (it does not inherit the dense connection's); the factor
    kinds name the forms that rebuild them, and an unknown kind is refused naming it."""
    from neuroimagery.nn import SOM, Kohonen, Sanger
    from neuroimagery.nn.local import LocalConnection
    from neuroimagery.nn.seeding import participant_generators

    dense = AllToAll(4, 3, rules=Hebbian(0.1))
    assert [f.name for f in forms.forms_of(dense, Hebbian(0.1))] == ["hebbian_shared", "hebbian_indexed", "plain"]
    assert [f.name for f in forms.forms_of(dense, Delta(0.1))] == ["delta_binary", "plain"]
    assert [f.name for f in forms.forms_of(dense, Sanger(0.1))] == ["plain"]
    local = LocalConnection(3, 1.0, participant_generators(0, 1))
    assert [f.name for f in forms.forms_of(local, Delta(0.1))] == ["index", "sparse", "dense", "restricted"]
    assert [f.name for f in forms.forms_of(local, Hebbian(0.1))] == ["restricted"]
    som = SOM((3, 3), 5)
    assert [f.name for f in forms.forms_of(som, Kohonen())] == ["repeated", "factored", "windowed", "online"]
    assert forms.factor_form({"kind": "som_windowed"}).name == "windowed"
    assert {forms.factor_form({"kind": k}).name for k in ("hebbian_shared", "hebbian_indexed")} == {"hebbian_shared", "hebbian_indexed"}
    with pytest.raises(ValueError, match="unknown factor kind 'som_online'"):
        forms.rebuild(som, {"kind": "som_online"})


def test_a_form_registered_for_a_new_rule_is_chosen_and_keeps_its_factors():
    """``@register(Rule, Learner)`` on a Form subclass is all a new implementation needs: 'auto'
    picks it where it applies, it records its factors in ``learnt_factors`` and rebuilds from them."""
    from neuroimagery.nn import Connection, Rule

    class Scale(Rule):  # w <- w * (1 - eta) per step, whatever the activity
        def __init__(self, eta):
            super().__init__()
            self.eta = eta

        def delta(self, weight, **_):
            return -self.eta * weight

    @forms.register(Scale, Connection)
    class ScaleClosed(forms.Form):
        name, kind = "scale_closed_test", "scale_closed_test"

        def run(self, conn, rule, call):
            T = call.pre.shape[-2]
            conn.weight.mul_((1 - rule.eta) ** T)
            return {"kind": self.kind, "factor": (1 - rule.eta) ** T}

        def rebuild(self, conn, f):
            conn.weight.mul_(f["factor"])

    try:
        a, b, c = (AllToAll(3, 2, participants=2, seed=1, rules=Scale(0.5)) for _ in range(3))
        a.learn(torch.ones(4, 3), torch.ones(4, 2), sequence=True)
        b.learn(torch.ones(4, 3), torch.ones(4, 2), sequence=True, method="plain")
        assert a.learnt_factors["kind"] == "scale_closed_test" and b.learnt_factors is None
        assert torch.allclose(a.weight, b.weight)
        forms.rebuild(c, a.learnt_factors)
        assert torch.equal(c.weight, a.weight)
    finally:  # leave the registry as it was
        forms._FORMS[Connection].pop(Scale)
        forms._KINDS.pop("scale_closed_test")


@pytest.mark.parametrize("rule", [Hebbian(0.2), Hebbian(0.2, form="instar"), Delta(0.1, reduction="mean")])
def test_a_local_connection_applies_any_rule_as_the_dense_rule_restricted(rule):
    """A local connection is the dense connection with the weights outside its receptive fields
    fixed at zero: any rule's change is the dense rule's at the stored weights (the delta rule by
    its own forms, others by the restricted dense change)."""
    from neuroimagery.nn.local import LocalConnection
    from neuroimagery.nn.seeding import participant_generators

    side, P = 3, 2
    local = LocalConnection(side, 1.0, participant_generators(0, P), init=(0.0, 0.5), rules=rule)
    n = side ** 3
    mask = torch.stack([local.dense(p) != 0 for p in range(P)])
    W0 = torch.stack([local.dense(p) for p in range(P)])
    g = torch.Generator().manual_seed(1)
    x, y = torch.rand(P, 4, n, generator=g), torch.rand(P, 4, n, generator=g)
    if isinstance(rule, Delta):  # the actual output at the current weights, and the target
        want = W0 + rule.delta(W0, pre=x, post=torch.bmm(x, W0.transpose(1, 2)), target=y)
        local.learn(pre=x, target=y)
    else:
        want = W0 + rule.delta(W0, pre=x, post=y)
        local.learn(pre=x, post=y)
    got = torch.stack([local.dense(p) for p in range(P)])
    assert not torch.allclose(got, W0)
    assert torch.allclose(got, want * mask, atol=1e-6)
