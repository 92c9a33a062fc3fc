"""The blocks' fast read-outs (nn/readout.py) give the numbers of the plain products, check a
configuration once and the values at every call unless the caller checked them, and follow the
weights when they change."""
from __future__ import annotations

import pytest
import torch

from neuroimagery.nn import SOM, AllToAll, Hebbian
from neuroimagery.nn.readout import binary_rows


def _conn(P=3, n_in=12, n_out=5):
    return AllToAll(n_in, n_out, participants=P, seed=4, rules=Hebbian(0.1))


def test_fast_products_equal_the_dense_product():
    c = _conn()
    g = torch.Generator().manual_seed(0)
    x = (torch.rand(3, 4, 12, generator=g) < 0.3).float()
    assert torch.allclose(c.net_binary(x), c.net(x), atol=1e-6)
    graded = x * torch.rand(3, 4, 12, generator=g)
    assert torch.allclose(c.net_sparse(graded), c.net(graded), atol=1e-6)
    for p in range(3):
        assert torch.allclose(c.net_of(p, graded[p, 0]), c.net(graded)[p, 0], atol=1e-6)
    y = torch.rand(3, 4, 5, generator=g)
    assert torch.allclose(c.net_reverse(y), torch.bmm(y, c.weight), atol=1e-6)
    rows = x.reshape(12, 12)
    group = torch.arange(3).repeat_interleave(4)
    assert torch.allclose(c.net_binary(rows, group), c.net(x).reshape(12, 5), atol=1e-6)
    d = _conn()
    both = binary_rows([c, d], group * 2 + 1, rows)  # block 1 (d) of each row's participant
    assert torch.allclose(both, d.net(x).reshape(12, 5), atol=1e-6)


def test_the_transposed_weights_follow_learning():
    c = _conn()
    x = (torch.rand(3, 2, 12, generator=torch.Generator().manual_seed(1)) < 0.5).float()
    before = c.net_binary(x)
    c.learn(x, torch.ones(3, 2, 5))
    after = c.net_binary(x)
    assert not torch.allclose(before, after)
    assert torch.allclose(after, c.net(x), atol=1e-6)


def test_checks_run_once_per_configuration_and_values_unless_checked():
    c = _conn()
    good = torch.rand(3, 2, 12)
    c(good)
    with pytest.raises(ValueError, match="must end in shape"):
        c(torch.rand(3, 2, 11))
    with pytest.raises(ValueError, match="participant"):
        c(torch.rand(2, 2, 12))
    bad = good.clone()
    bad[0, 0, 0] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        c(bad)  # the configuration is known; the values are still checked
    assert torch.isnan(c(bad, checked=True)).any()  # the caller vouched for the batch


def test_som_reads_out_through_its_own_methods():
    som = SOM((2, 3), 8, participants=2, seed=1)
    x = torch.rand(2, 3, 8, generator=torch.Generator().manual_seed(2))
    assert torch.allclose(som.net(x), torch.bmm(x, som.weight.transpose(1, 2)), atol=1e-6)
    d = som.distances(x)
    for p in range(2):
        assert torch.allclose(som.distances_of(p, x[p, 0]), d[p, 0], atol=1e-5)
        part = som.part_distances(x[p, 0, 3:], 3, 8, participant=p)
        full = ((x[p, 0, 3:] - som.weight[p, :, 3:]) ** 2).sum(-1) - (x[p, 0, 3:] ** 2).sum()
        assert torch.allclose(part, full, atol=1e-5)
    prods = som.part_products(x[0, :, :3], 0, 3)
    assert torch.allclose(prods, torch.einsum("pui,ki->pku", som.weight[..., :3], x[0, :, :3]), atol=1e-6)
    assert torch.equal(som.prototypes(torch.tensor([4, 1]), 2, 5)[1], som.weight[1, 1, 2:5])
