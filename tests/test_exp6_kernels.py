"""Experiment 6's compiled loops and batched comparisons give the numbers of the torch code they
stand for: a local connection's products and sparse delta-rule change
(:mod:`neuroimagery.nn.local_kernel`), the dot maps and the largest
cluster (:mod:`neuroimagery.models.voxel_code_kernel`),
the coarse comparison in blocks of rows, the local refinement that compares only the rows that
rose, and the forward models learnt side by side on two threads."""
import pytest
import torch
from conftest import make_cfg

from neuroimagery.config import validate
from neuroimagery.experiments.exp6 import protocol as exp6
from neuroimagery.models import voxel_code as vc
from neuroimagery.models import voxel_code_kernel
from neuroimagery.models.rotation_3d import AXES, fill_offsets
from neuroimagery.nn import Delta, compiled, local_kernel, seeding
from neuroimagery.nn.functional import intra_op_threads
from neuroimagery.nn.local import LocalConnection

needs_numba = pytest.mark.skipif(not local_kernel.available(torch.zeros(1)), reason="numba is not installed")


def _train_and_apply(dtype, offset_set=None):
    """A local connection trained by the delta rule on graded dot maps (sparse path), then its
    products of sparse and dense rows and of a (P, B, n) input."""
    side, P, B = 9, 3, 4
    c = LocalConnection(side, 2, seeding.participant_generators(0, P), rules=Delta(0.1), offset_set=offset_set).to(dtype)
    c.train()
    g = torch.Generator().manual_seed(1)
    for _ in range(6):
        pos = ((torch.rand(P * B, 5, 3, generator=g, dtype=torch.float64) - 0.5) * (side - 4)).float()
        x = vc.blobs(pos, side, 0.7).reshape(P, B, -1).to(dtype)
        y = vc.blobs(pos.flip(-1), side, 0.7).reshape(P, B, -1).to(dtype)
        c.learn(pre=x, target=y)
    c.learn(pre=x, post=c.net(x), target=x)  # the output given
    dense = torch.rand(7, side ** 3, generator=g).to(dtype)
    pts = ((torch.rand(7, 3, 3, generator=g, dtype=torch.float64) - 0.5) * 5).float()
    sparse = vc.blobs(pts, side, 0.7).to(dtype)
    group = torch.tensor([0, 1, 2, 2, 1, 0, 1])
    assert float((sparse != 0).float().mean()) <= 0.25 < float((dense != 0).float().mean())
    return [c.weight.clone(), c.net_rows(sparse, group), c.net_rows(dense, group), c.net(dense[:6].reshape(P, 2, -1))]


@needs_numba
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("offsets", ["ball", "column"])
def test_local_kernels_equal_the_torch_code(monkeypatch, dtype, offsets):
    offset_set = fill_offsets(3, 1) if offsets == "column" else None
    fast = _train_and_apply(dtype, offset_set)
    monkeypatch.setattr(compiled, "numba", None)
    plain = _train_and_apply(dtype, offset_set)
    assert not torch.allclose(fast[0], LocalConnection(9, 2, seeding.participant_generators(0, 3),
                                                       offset_set=offset_set).weight.to(dtype))
    for a, b in zip(fast, plain):
        assert a.dtype == b.dtype and torch.allclose(a, b, rtol=0, atol=1e-6)


@needs_numba
def test_dot_map_kernel_equals_the_torch_code(monkeypatch):
    g = torch.Generator().manual_seed(0)
    pts = ((torch.rand(40, 24, 3, generator=g, dtype=torch.float64) - 0.5) * 19).float()  # some dots at the edge
    a = vc.blobs(pts, 18, 0.7)
    monkeypatch.setattr(compiled, "numba", None)
    b = vc.blobs(pts, 18, 0.7)
    assert 0 < float((b != 0).float().mean()) < 0.5 and bool((b == 1).any())
    assert torch.allclose(a, b, rtol=0, atol=1e-7)


def _model():
    cfg = validate(make_cfg("experiment=exp6", "logger=none", "experiment.grid=12", "participants=1"))
    return exp6._model(cfg, [0])


def _coarse_match_plain(model, target, comp, R):
    """The coarse comparison formed at once for every row (the formula of its docstring)."""
    (pt, wt), (pc, wc) = target, comp
    turned = torch.einsum("rij,rcj->rci", R, pc)
    d2 = ((pt * pt).sum(-1).unsqueeze(2) + (turned * turned).sum(-1).unsqueeze(1)
          - 2.0 * pt @ turned.transpose(1, 2)).clamp_min(0.0)
    return torch.einsum("rt,rtc,rc->r", wt, torch.exp(-d2 / (2.0 * model.cube_voxels ** 2)), wc)


def _refine_plain(model, target, comp, R, score):
    """The local refinement comparing every row at every step."""
    small = {d: torch.stack([vc.axis_rotation(a, sg * d) for a in AXES for sg in (-1.0, 1.0)])
             for d in model.p.search.refine}
    rows = torch.arange(R.shape[0])
    for d in model.p.search.refine:
        for _ in range(model.p.search.refine_steps):
            cand = small[d].unsqueeze(0) @ R.unsqueeze(1)
            sc = torch.stack([_coarse_match_plain(model, target, comp, cand[:, j]) for j in range(cand.shape[1])], -1)
            best = sc.argmax(-1)
            up = sc[rows, best] > score
            if not up.any():
                break
            R = torch.where(up.view(-1, 1, 1), cand[rows, best], R)
            score = torch.where(up, sc[rows, best], score)
    return R, score


def test_coarse_comparison_and_refinement_equal_the_plain_forms():
    model = _model()
    g = torch.Generator().manual_seed(2)
    n = model.side ** 3
    rows = 2 * 8 + 3  # blocks of rows, and a remainder
    pts = (torch.rand(rows, 10, 3, generator=g, dtype=torch.float64) - 0.5) * (model.side - 4)
    target = vc.blobs(pts.float(), model.side, 1.0)
    comp = vc.blobs((pts @ vc.axis_rotation("y", 35.0).T).float(), model.side, 1.0)
    assert target.shape == (rows, n)
    ct, cc = model.coarse_code(target), model.coarse_code(comp)
    R = torch.stack([vc.axis_rotation("x", 7.0 * k) for k in range(rows)])
    assert torch.allclose(model.coarse_match(ct, cc, R), _coarse_match_plain(model, ct, cc, R), rtol=1e-12, atol=0)
    score = model.coarse_match(ct, cc, R)
    Ra, sa = model.refine(ct, cc, R, score)
    Rb, sb = _refine_plain(model, ct, cc, R, score)
    assert (sb > score).any() and not torch.allclose(Rb, R)  # the refinement moves some rows
    assert torch.allclose(Ra, Rb, rtol=0, atol=1e-12) and torch.allclose(sa, sb, rtol=1e-12, atol=0)


@needs_numba
def test_largest_cluster_kernel_equals_spreading_labels(monkeypatch):
    g = torch.Generator().manual_seed(4)
    side = 9
    masks = (torch.rand(12, side ** 3, generator=g) < torch.linspace(0.02, 0.4, 12).unsqueeze(1)).float()
    masks[0] = 0.0
    a = vc.largest_cluster(masks, side)
    monkeypatch.setattr(compiled, "numba", None)
    b = vc.largest_cluster(masks, side)
    assert a.dtype == b.dtype and torch.equal(a, b) and b[0] == 0 and len(set(b.tolist())) > 5



def test_forward_models_learnt_side_by_side_equal_one_after_the_other():
    cfg = validate(make_cfg("experiment=exp6", "logger=none", "experiment.grid=10", "participants=2",
                            "experiment.fm.images=12", "experiment.fm.dots=6"))
    weights = []
    for threads in (1, 2):
        model = exp6._model(cfg, [0, 1])
        model.train()
        with intra_op_threads(threads):
            with intra_op_threads(1, cap=True):  # as exp6.train_model
                exp6.train_forward_models(model, cfg, [0, 1])
        weights.append(torch.stack([c.weight for c in model.fm]))
    init = torch.stack([c.weight for c in exp6._model(cfg, [0, 1]).fm])
    assert not torch.allclose(weights[0], init)
    assert torch.allclose(weights[0], weights[1], rtol=0, atol=1e-7)
