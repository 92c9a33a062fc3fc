"""The fused online SOM kernel (nn/som_online.py) against the plain step (SOM.step: Kohonen.delta
added to the weights, winners by a fresh distance computation).

Tolerance: the kernel updates float32 weights with ``lerp`` instead of ``w + h (x - w)`` and keeps
the distances by exact recurrences in float64, so the weights agree to float32 rounding
accumulated over the steps (``atol=1e-5`` on weights of order 0.1-1); the winners must be identical.
"""
import pytest
import torch

from neuroimagery.nn import SOM, Kohonen, participant_generators, seeding
from neuroimagery.nn import som_online


def plain(som, X, order, labels=None):
    """The reference: one SOM.step per presentation."""
    P = som.participants
    X = X.unsqueeze(0).expand(P, -1, -1) if X.dim() == 2 else X
    p = torch.arange(P)
    wins = []
    for t in range(order.shape[1]):
        s = order[:, t]
        wins.append(som.step(X[p, s], None if labels is None else labels[p, s]))
    return torch.stack(wins, 1)


def pair(shape, n_in, cutoff=None, **kw):
    a, b = SOM(shape, n_in, **kw), SOM(shape, n_in, **kw)
    if cutoff is not None:
        a.rule.cutoff = b.rule.cutoff = cutoff
    return a, b


def kernel(som, X, order, labels=None, fold=True, chunk=som_online.CHUNK):
    """The trainer as SOM.fit calls it: on the patterns its rule has scaled (a supervised map
    whose weights sum to 1 divides each input by its sum, as SOM.step does)."""
    P = som.participants
    X = som.rule.scale_input(X)
    X = X.unsqueeze(0).expand(P, -1, -1) if X.dim() == 2 else X
    lab = None if labels is None else labels.unsqueeze(0).expand(P, -1)
    return som_online.fit_online(som, X, order, lab, fold=fold, chunk=chunk)


@pytest.mark.parametrize("fold", [True, False])
@pytest.mark.parametrize("shape,cutoff,binary", [((9, 7), None, True), ((9, 7), 0.0, False), ((40,), None, False)])
def test_online_kernel_equals_plain_step(shape, cutoff, binary, fold):
    g = torch.Generator().manual_seed(1)
    X = torch.rand(25, 120, generator=g)
    X = (X > 0.7).float() if binary else X
    a, b = pair(shape, 120, cutoff, participants=3, seed=5, eta=0.4, sigma=4.0, eta_final=0.02, sigma_final=0.5,
                iterations=300)
    order = seeding.randint(participant_generators(7, 3), 25, (300,))  # 300: not a multiple of the chunk
    wa = plain(a, X, order)
    wb = b.fit(X, order=order, method="online") if fold else kernel(b, X, order, fold=False)
    assert torch.equal(wa, wb)
    assert torch.allclose(a.weight, b.weight, atol=1e-5)
    assert int(b.steps) == int(a.steps) == 300


def test_online_kernel_any_chunk_length_equals_plain_step():
    X = torch.rand(20, 60, generator=torch.Generator().manual_seed(8))
    order = seeding.randint(participant_generators(3, 2), 20, (90,))
    ref = SOM((6, 6), 60, participants=2, seed=2, sigma=3.0, iterations=90)
    wa = plain(ref, X, order)
    for chunk in (1, 7, 200):
        som = SOM((6, 6), 60, participants=2, seed=2, sigma=3.0, iterations=90)
        assert torch.equal(kernel(som, X, order, chunk=chunk), wa)
        assert torch.allclose(som.weight, ref.weight, atol=1e-5)


@pytest.mark.parametrize("fold", [True, False])
def test_online_kernel_supervised_normalised_equals_plain_step(fold):
    # sigma 0.5 on a 6x5 map: most units are out of reach of each step, yet the rule normalises them all
    X = torch.rand(12, 50, generator=torch.Generator().manual_seed(2))
    labels = torch.arange(12) % 30
    a, b = pair((6, 5), 50, participants=2, seed=3, eta=0.3, sigma=0.5, iterations=100, supervised=True)
    order = seeding.randint(participant_generators(1, 2), 12, (100,))
    plain(a, X, order, labels.unsqueeze(0).expand(2, -1))
    kernel(b, X, order, labels, fold=fold)
    assert torch.allclose(a.weight, b.weight, atol=1e-5)
    assert torch.allclose(b.weight.sum(-1), torch.ones(2, 30), atol=1e-5)


def test_online_kernel_continues_where_a_fit_stopped():
    X = torch.rand(20, 30, generator=torch.Generator().manual_seed(3))
    a, b = pair((6, 6), 30, participants=2, seed=1, iterations=150, sigma=3.0)
    order = seeding.randint(participant_generators(2, 2), 20, (150,))
    wa = plain(a, X, order)
    wb = torch.cat([b.fit(X, iterations=70, order=order[:, :70], method="online"),
                    b.fit(X, iterations=80, order=order[:, 70:], method="online")], 1)
    assert torch.equal(wa, wb)
    assert torch.allclose(a.weight, b.weight, atol=1e-5)


def test_online_kernel_batched_equals_solo():
    X = torch.rand(15, 40, generator=torch.Generator().manual_seed(4))
    order = seeding.randint(participant_generators(8, 3), 15, (120,))
    batch = SOM((5, 6), 40, generators=participant_generators(3, 3), iterations=120)
    wb = batch.fit(X, order=order, method="online")
    for q in range(3):
        solo = SOM((5, 6), 40, generators=participant_generators(3, [q]), iterations=120)
        ws = solo.fit(X, order=order[q:q + 1], method="online")
        assert torch.equal(ws[0], wb[q])
        assert torch.allclose(solo.weight[0], batch.weight[q], atol=1e-6)


def test_truncated_neighbourhood_is_an_option_that_changes_the_map():
    X = torch.rand(20, 30, generator=torch.Generator().manual_seed(5))
    order = seeding.randint(participant_generators(2, 1), 20, (60,))
    exact, wide, narrow = (SOM((12, 12), 30, seed=2, sigma=4.0, iterations=60) for _ in range(3))
    for m in (exact, wide, narrow):
        m.rule.cutoff = 0.0
    exact.fit(X, order=order, method="online")
    P_X = X.unsqueeze(0)
    w0 = narrow.weight.clone()
    som_online.fit_online(wide, P_X, order, truncate=100.0)  # reaches the whole map: the exact step
    wins = som_online.fit_online(narrow, P_X, order[:, :1], truncate=1.0)
    assert torch.allclose(exact.weight, wide.weight, atol=1e-6)
    # after one truncated step only the units within 1 sigma (4 grid units) of the winner moved
    r, c = divmod(int(wins[0, 0]), 12)
    moved = (narrow.weight[0] != w0[0]).any(-1).reshape(12, 12)
    rr, cc = torch.meshgrid(torch.arange(12), torch.arange(12), indexing="ij")
    inside = ((rr - r).abs() <= 4) & ((cc - c).abs() <= 4)
    assert bool(moved[inside].all()) and not bool(moved[~inside].any())
    with pytest.raises(ValueError, match="truncate"):
        som_online.fit_online(narrow, P_X, order, truncate=0.0)


def test_kernel_declines_a_rule_that_changes_the_step():
    class Halved(Kohonen):
        def delta(self, weight, **kw):
            return 0.5 * super().delta(weight, **kw)

    assert som_online.supports(Kohonen()) and not som_online.supports(Halved())
    X = torch.rand(10, 8, generator=torch.Generator().manual_seed(6))
    order = seeding.randint(participant_generators(1, 1), 10, (40,))
    a, b = pair((3, 3), 8, seed=0, iterations=40)
    a.rule, b.rule = Halved(0.1, 1.5, 40), Halved(0.1, 1.5, 40)
    plain(a, X, order)
    b.fit(X, order=order, method="online")  # the plain loop, with the subclass's delta
    assert torch.allclose(a.weight, b.weight, atol=1e-7)


@pytest.mark.slow
def test_online_kernel_equals_plain_step_at_full_size():
    # PFC_2's size (64x64 units, 2,048 inputs, 196 sparse patterns), the schedule compressed so that
    # sigma runs from 32 to 0.5 in 200 steps: map-wide and narrow neighbourhoods both occur
    X = (torch.rand(196, 2048, generator=torch.Generator().manual_seed(0)) > 0.9).float()
    a, b = pair((64, 64), 2048, participants=2, seed=0, iterations=200)
    order = seeding.randint(participant_generators(1, 2), 196, (200,))
    assert torch.equal(plain(a, X, order), b.fit(X, order=order, method="online"))
    assert torch.allclose(a.weight, b.weight, atol=1e-5)
