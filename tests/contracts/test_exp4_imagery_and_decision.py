"""Experiment 4 contracts X4.6-X4.8, X4.10 and X4.12 (docs/contracts.md): the forward models, the
matching of POCp with the target and the flipped target (C10), the time-outs and the accumulator
deciding rapidly only at a large overlap."""
import pytest
import torch
from support_ch6 import forward_fn, forward_model_shape, item_rows

from neuroimagery.experiments.exp4 import protocol as exp4
from neuroimagery.models.pmcd_leak import QUIET_SHARE, misaligned_pairs
from neuroimagery.vision.edges import iou, rotate


def test_x4_6_forward_models_keep_the_shape(trained4):
    e = trained4.e
    for name in (e.train_set, e.gen1_set):
        for move, angle in ((0, e.step_deg), (2, -e.step_deg)):
            r = forward_model_shape(forward_fn(trained4, move), trained4.bank(name).maps, angle, e.map_size)
            print(f"X4.6 {name} move {move}: {r}")
            assert r[1][1] >= 0.6
            assert 0.8 <= r["ratio"] <= 1.25
            for k in (1, 2):
                assert r[k][k] > r[k][k - 1] and r[k][k] > r[k][k + 1]


def test_x4_7_an_exact_rotation_overlaps_the_target(trained4):
    m, e, bank = trained4.model, trained4.e, trained4.bank(trained4.e.train_set)
    rows, size = item_rows(bank), e.map_size
    tg, im = [], []
    for i, o, a, ap in rows:
        for j, o2, b, ap2 in rows:
            if o2 == o and ap2 == ap and a != b:
                tg.append(bank.maps[i]), im.append(rotate(bank.maps[j].reshape(size, size), a - b).reshape(-1))
    tg, im = torch.stack(tg), torch.stack(im)
    share = m.overlap(tg, im) / tg.sum(-1).clamp_min(1)
    ok = float((share >= 0.9).float().mean())
    print(f"X4.7 overlap of an exact rotation: mean {float(share.mean()):.3f}, share >= 0.9 {ok:.3f}")
    assert ok >= 0.9


def test_x4_8_flipped_target_is_the_mirror(trained4):
    m, bank = trained4.model, trained4.bank(trained4.e.train_set)
    rows = item_rows(bank)
    idx = {(o, a, ap): i for i, o, a, ap in rows}
    aps = sorted({ap for *_, ap in rows})
    pairs = [(i, idx[(o, a, ap2)]) for i, o, a, ap in rows for ap2 in aps if ap2 != ap]
    P, size = m.participants, trained4.e.map_size
    target = bank.maps[[i for i, _ in pairs]].unsqueeze(0).expand(P, -1, -1)
    mirror = bank.maps[[j for _, j in pairs]].unsqueeze(0).expand(P, -1, -1)
    flipped = m.flip_target(target)
    v = float(iou(flipped.reshape(P, -1, size, size), mirror.reshape(P, -1, size, size)).mean())
    pocp = m.forward_step(mirror, torch.ones(P, len(pairs), dtype=torch.long))  # the still step at alignment
    more = float((m.overlap(flipped, pocp) > m.overlap(target, pocp)).float().mean())
    print(f"X4.8 C10 (about PPCt's axis): IoU with the true mirror {v:.3f}; flipped > target overlap {more:.3f}")
    assert v >= 0.5 and more >= 0.9


def test_x4_10_time_outs_are_rare(trained4):
    cfg = trained4.cfg
    df, _, _ = exp4.run_tests(cfg, trained4.model, trained4.eye)
    d = df[df["condition"] == "none"]
    share = 1 - d.groupby("test")["decided"].mean()
    print(f"X4.10 time-out share (quick, condition none): {share.round(3).to_dict()}")
    assert (share < 0.10).all()


def test_x4_12_the_accumulator_decides_rapidly_only_at_a_large_overlap(trained4):
    """(a) each image of sets A and B against itself decides (either way) within one step in >= 90 %;
    (b) misaligned same-object pairs (both appearances, not read) decide within four steps in <= 10 %."""
    m = trained4.model
    print(f"X4.12 leak {m.leak.tolist()}, gain {m.input_gain.tolist()}")
    ok = []
    for name in (trained4.e.train_set, trained4.e.gen1_set):  # measure both sets, then judge
        bank = trained4.bank(name)
        objects, _, angles = bank.structure()
        x = bank.maps.unsqueeze(0).expand(m.participants, -1, -1)
        large = m.hold(m.pair_evidence(x, x), steps=1).decided.float().mean(1)
        t, c = misaligned_pairs(objects, angles)
        small = m.hold(m.pair_evidence(x[:, t], x[:, c]), steps=4).decided.float().mean(1)
        print(f"X4.12 set {name}: identical decide within 1 step {large.tolist()} (>= 0.9); "
              f"misaligned decide within 4 steps {small.tolist()} (<= {QUIET_SHARE})")
        ok += [bool((large >= 0.9).all()), bool((small <= QUIET_SHARE).all())]
    assert all(ok), ok
