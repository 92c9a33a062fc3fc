"""Packed binary rows (nn.binary): exact packing, bit counts and the distinct-pair grouping that the
Exp 4 trial loop uses to compute each forward-model prediction once."""
import pytest
import torch

from neuroimagery.nn.binary import binary_matmul, binary_matmul_rows, pack_bits, popcount, sparse_matmul, unique_rows, unpack_bits


@pytest.mark.parametrize("n", [1, 63, 64, 100, 1024])
def test_pack_round_trip_and_popcount(n):
    g = torch.Generator().manual_seed(n)
    x = torch.rand(3, 5, n, generator=g) < 0.3
    w = pack_bits(x)
    assert w.dtype == torch.int64 and w.shape == (3, 5, -(-n // 64))
    assert torch.equal(unpack_bits(w, n), x)
    assert torch.equal(popcount(w), x.sum(-1))
    assert torch.equal(pack_bits(x.float()), w)  # 0/1 floats pack as the bools do
    a, b = x[0], x[1]
    assert torch.equal(popcount(pack_bits(a) & pack_bits(b)), (a & b).sum(-1))  # overlap = bits on in both


def test_unique_rows_groups_equal_pairs_only():
    g = torch.Generator().manual_seed(0)
    base = torch.rand(6, 200, generator=g) < 0.2
    pick = torch.tensor([0, 1, 0, 2, 1, 0, 3, 5, 4, 0])
    group = torch.tensor([7, 1, 7, 2, 1, 3, 0, 0, 0, 7])  # row 5: same image as row 0, other group
    gu, wu, inv = unique_rows(group, pack_bits(base[pick]))
    assert torch.equal(gu[inv], group) and torch.equal(unpack_bits(wu[inv], 200), base[pick])
    assert len(gu) == 7  # (7,0) x3, (1,1) x2 and five singles
    assert inv[0] == inv[2] == inv[9] and inv[1] == inv[4] and inv[0] != inv[5]


def test_products_of_distinct_pairs_equal_the_full_batch():
    g = torch.Generator().manual_seed(1)
    table = torch.randn(4, 128, 9, generator=g)
    x = (torch.rand(30, 128, generator=g) < 0.15)[torch.randint(0, 30, (50,), generator=g)]
    group = torch.randint(0, 4, (50,), generator=g)
    full = binary_matmul_rows(table, group, x.float())
    gu, wu, inv = unique_rows(group, pack_bits(x))
    assert torch.equal(binary_matmul_rows(table, gu, unpack_bits(wu, 128))[inv], full)
    ref = torch.einsum("ni,nio->no", x.float(), table[group])
    assert torch.allclose(full, ref, atol=1e-5)


def test_unique_rows_falls_back_to_exact_grouping_when_hashes_collide(monkeypatch):
    from neuroimagery.nn import binary

    g = torch.Generator().manual_seed(2)
    x = (torch.rand(8, 70, generator=g) < 0.3)[torch.tensor([0, 1, 0, 2, 3, 3, 4, 5, 6, 7, 0])]
    group = torch.zeros(11, dtype=torch.long)
    monkeypatch.setattr(binary, "_hash_weights", lambda width: torch.zeros(width, dtype=torch.float64))  # every row one hash
    gu, wu, inv = unique_rows(group, pack_bits(x))
    assert len(gu) == 8 and torch.equal(unpack_bits(wu[inv], 70), x)


def test_unique_rows_come_in_ascending_group_order():
    g = torch.Generator().manual_seed(3)
    x = torch.rand(40, 64, generator=g) < 0.5
    group = torch.randint(0, 5, (40,), generator=g)
    gu, wu, inv = unique_rows(group, pack_bits(x))
    assert torch.equal(gu, gu.sort().values) and torch.equal(gu[inv], group) and torch.equal(unpack_bits(wu[inv], 64), x)


def test_sparse_matmul_equals_the_dense_product_on_graded_input():
    g = torch.Generator().manual_seed(3)
    w = torch.randn(2, 40, 7, generator=g)  # (P, in, out): W transposed
    x = torch.randn(2, 5, 40, generator=g) * (torch.rand(2, 5, 40, generator=g) < 0.3)  # graded, mostly zero
    x[1, 2] = 0.0  # an empty row
    torch.testing.assert_close(sparse_matmul(w, x), torch.bmm(x, w), rtol=1e-5, atol=1e-5)
    b = (x != 0).float()
    torch.testing.assert_close(sparse_matmul(w, b), binary_matmul(w, b))


def test_cover_of_a_bool_map_is_the_max_pooled_cover_of_its_0_1_values():
    """population_cover of bool maps (shifted ORs) equals the max-pooled cover of the same maps as
    0/1 floats, at every reach and at the border."""
    from neuroimagery.nn import population_cover

    g = torch.Generator().manual_seed(3)
    for size, reach in ((5, 1), (5, 3), (32, 1), (32, 2), (7, 9)):
        b = torch.rand(2, 20, size * size, generator=g) > 0.85
        cover = population_cover(b, size, reach)
        assert cover.dtype == torch.bool and cover.shape == b.shape
        assert torch.equal(cover, population_cover(b.float(), size, reach) > 0.5), (size, reach)
