"""Experiment 3 contracts X3.1-X3.6 and X3.11 (docs/contracts.md): the supervised Kohonen step, the
posture maps C2/C3, the choice of the move by M1_1 -> M1_2, and the less certain codes of unseen
objects."""
import torch
from support_ch6 import entropy_bits, item_rows, assert_supervised_rate

from neuroimagery.nn.functional import gain_field, softmax_probabilities


def _codes(t, maps):
    P = t.model.participants
    x = maps.unsqueeze(0).expand(P, -1, -1)
    return t.model.posture(t.model.c2, x), t.model.posture(t.model.c3, x)


def _move_probs(t, target, rotated):
    """P(n1, n2, n3) of a step, the model's own read-out, ``(P, B, 3)``."""
    P = t.model.participants
    return t.model.move_probabilities(target.unsqueeze(0).expand(P, -1, -1), rotated.unsqueeze(0).expand(P, -1, -1))


def test_x3_1_supervised_step_moves_at_the_stated_rate(trained3):
    m = trained3.model
    assert_supervised_rate(trained3, (m.c2, m.c3), trained3.e.posture.angles, trained3.e.posture.eta, "X3.1")


def test_x3_2_x3_3_posture_maps_read_the_trained_posture(trained3):
    bank = trained3.bank(trained3.e.train_set)
    labels = bank.angle_labels(trained3.e.posture.angles)
    ss, pmc1 = _codes(trained3, bank.maps)
    acc2 = (ss.argmax(-1) == labels).float().mean(-1)
    acc3 = (pmc1.argmax(-1) == labels).float().mean(-1)
    agree = (ss.argmax(-1) == pmc1.argmax(-1)).float().mean()
    print(f"X3.2 C2 {acc2.tolist()} C3 {acc3.tolist()}; X3.3 agreement {float(agree):.3f}")
    assert (acc2 >= 0.95).all() and (acc3 >= 0.95).all()
    assert agree >= 0.95


def test_x3_4_coinciding_codes_stop_the_rotation(trained3):
    """Target: the training look; rotated object: a fresh look at the same item (X3.13); pairs whose
    SS and PMC_1 codes have the same strongest unit."""
    m, train = trained3.model, trained3.bank(trained3.e.train_set)
    fresh = trained3.looks(trained3.e.train_set)[1]
    P = m.participants
    pmc1 = m.posture(m.c3, train.maps.unsqueeze(0).expand(P, -1, -1))
    ss = m.posture(m.c2, fresh.unsqueeze(0).expand(P, -1, -1))
    coincide = pmc1.argmax(-1) == ss.argmax(-1)
    p_n2 = _move_probs(trained3, train.maps, fresh)[..., 1][coincide].mean()
    print(f"X3.4 P(n2) where SS and PMC_1 coincide {float(p_n2):.3f} ({int(coincide.sum())} of {coincide.numel()} pairs)")
    assert p_n2 >= 0.8


def test_x3_5_first_turn_goes_toward_the_target(trained3):
    bank = trained3.bank(trained3.e.train_set)
    rows = item_rows(bank)
    tg, rt, sign = [], [], []
    for i, o, a, ap in rows:
        for j, o2, b, ap2 in rows:
            if o2 == o and ap2 == ap and b != a:
                tg.append(i), rt.append(j), sign.append(1.0 if a > b else -1.0)  # target angle above: turn ccw (n3)
    pr = _move_probs(trained3, bank.maps[tg], bank.maps[rt])
    s = torch.tensor(sign)
    toward = torch.where(s > 0, pr[..., 2], pr[..., 0])
    share = float(toward.sum() / (pr[..., 0] + pr[..., 2]).sum())
    print(f"X3.5 share of first turns toward the target {share:.3f}")
    assert share >= 0.8


def test_x3_6_flat_codes_select_no_rotation(trained3):
    m = trained3.model
    nu = len(trained3.e.posture.angles)
    for level in (0.2, 0.4, 0.6, 0.8, 1.0):
        flat = torch.full((1, 1, nu), level)
        pr = softmax_probabilities(m.m1_2(gain_field(flat, flat).reshape(1, 1, nu * nu)), trained3.e.selection.tau)[0, 0]
        print(f"X3.6 level {level}: P(n1, n2, n3) = {[round(float(v), 3) for v in pr]}")
        assert int(pr.argmax()) == 1 and pr[1] >= 0.5


def test_x3_11_unseen_objects_give_less_certain_codes(trained3):
    e = trained3.e
    ent = {}
    for name in (e.train_set, e.gen1_set, e.gen2_set):
        bank = trained3.bank(name)
        ss, pmc1 = _codes(trained3, bank.maps)
        rows = item_rows(bank)
        tg, rt = zip(*[(i, j) for i, o, a, ap in rows for j, o2, b, ap2 in rows if o2 == o and ap2 == ap])
        move = _move_probs(trained3, bank.maps[list(tg)], bank.maps[list(rt)])
        ent[name] = [float(entropy_bits(v).mean()) for v in (ss, pmc1, move)]
    print("X3.11 entropy (bits) SS / PMC_1 / M1_2: " + "; ".join(f"{k} {[round(v, 3) for v in x]}" for k, x in ent.items()))
    a, b, c = ent[e.train_set], ent[e.gen1_set], ent[e.gen2_set]
    assert a[0] < b[0] < c[0] and a[1] < b[1] < c[1]
    assert a[2] < b[2]
