"""Experiment 3 contracts X3.7-X3.9 (docs/contracts.md): the forward model C6 and the matching
of PP_2 with PFC_1 (C7-C9)."""
import torch
from support_ch6 import forward_fn, forward_model_shape, item_rows

from neuroimagery.vision.edges import rotate


def test_x3_7_forward_model_keeps_the_shape(trained3):
    e = trained3.e
    for name in (e.train_set, e.gen1_set):
        for move, sign in ((2, 1.0), (0, -1.0)):
            r = forward_model_shape(forward_fn(trained3, move), trained3.bank(name).maps, sign * e.step_deg, e.map_size)
            print(f"X3.7 {name} move {move}: {r}")
            assert r[1][1] >= 0.6
            assert 0.8 <= r["ratio"] <= 1.25
            for k in (1, 2):
                assert r[k][k] > r[k][k - 1] and r[k][k] > r[k][k + 1]


def _share(t, target, image):
    return t.model.uncovered(target, image).sum(-1) / target.sum(-1).clamp_min(1)


def test_x3_8_same_images_leave_little_uncovered_mirrors_much(trained3):
    e, bank = trained3.e, trained3.bank(trained3.e.train_set)
    maps, size = bank.maps, e.map_size
    assert float(_share(trained3, maps, maps).max()) == 0.0
    main = item_rows(bank)
    same_t, same_r = [], []
    for i, o, a, ap in main:
        for j, o2, b, ap2 in main:
            if o2 == o and ap2 == ap and a != b:
                same_t.append(maps[i]), same_r.append(rotate(maps[j].reshape(size, size), a - b).reshape(-1))
    same = _share(trained3, torch.stack(same_t), torch.stack(same_r))
    idx = {(o, a, ap): i for i, o, a, ap in item_rows(bank)}
    aps = sorted({ap for _, _, _, ap in item_rows(bank)})
    mir = [(i, idx[(o, a, ap2)]) for i, o, a, ap in item_rows(bank) for ap2 in aps if ap2 != ap]
    mirror = _share(trained3, maps[[i for i, _ in mir]], maps[[j for _, j in mir]])
    ok_same = float((same <= e.match_threshold).float().mean())
    ok_mirror = float((mirror > e.match_threshold).float().mean())
    print(f"X3.8 exact rotation: uncovered mean {float(same.mean()):.3f}, share <= 5 % {ok_same:.3f}; "
          f"mirror: uncovered mean {float(mirror.mean()):.3f}, share > 5 % {ok_mirror:.3f}")
    assert ok_same >= 0.9 and ok_mirror >= 0.9


def test_x3_9_imagined_rotation_to_the_target_matches_it(trained3):
    e, bank, m = trained3.e, trained3.bank(trained3.e.train_set), trained3.model
    maps, P = bank.maps, m.participants
    rows = item_rows(bank)
    groups = {}
    for i, o, a, ap in rows:
        for j, o2, b, ap2 in rows:
            if o2 == o and ap2 == ap and a != b:
                groups.setdefault(a - b, []).append((i, j))
    shares = {}
    for d, pairs in sorted(groups.items()):
        tg = maps[[i for i, _ in pairs]].unsqueeze(0).expand(P, -1, -1)
        x = maps[[j for _, j in pairs]].unsqueeze(0).expand(P, -1, -1)
        move = 2 if d > 0 else 0
        for _ in range(int(round(abs(d) / e.step_deg))):
            x = m.forward_step(x, torch.full(x.shape[:2], move, dtype=torch.long))
        shares[d] = float(_share(trained3, tg, x).mean())
    print("X3.9 uncovered by disparity: " + ", ".join(f"{d:+.0f}: {v:.3f}" for d, v in shares.items()))
    assert max(shares.values()) <= e.match_threshold
