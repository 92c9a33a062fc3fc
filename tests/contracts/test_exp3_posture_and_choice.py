"""Experiment 3 contracts X3.1-X3.6 (docs/contracts.md): the supervised Kohonen step, the posture
maps C2/C3, and the choice of the move by M1_1 -> M1_2."""
import torch
from support_ch6 import item_rows, rule_rate

from neuroimagery.nn.functional import gain_field, softmax_probabilities


def _codes(t, maps):
    P = t.model.participants
    x = maps.unsqueeze(0).expand(P, -1, -1)
    return t.model.posture(t.model.c2, x), t.model.posture(t.model.c3, x)


def _move_probs(t, target, rotated):
    """P(n1, n2, n3) of the first step, ``(P, B, 3)``."""
    m, P = t.model, t.model.participants
    pmc1 = m.posture(m.c3, target.unsqueeze(0).expand(P, -1, -1))
    ss = m.posture(m.c2, rotated.unsqueeze(0).expand(P, -1, -1))
    nu = ss.shape[-1]
    m11 = gain_field(pmc1, ss).reshape(P, -1, nu * nu)
    return softmax_probabilities(m.m1_2(m11), t.e.selection.tau)


def test_x3_1_supervised_step_moves_at_the_stated_rate():
    r = rule_rate(0.1)
    print(f"X3.1 relative change per step {r:.3f} (eta 0.1)")
    assert 0.05 <= r <= 0.2


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
    maps = trained3.bank(trained3.e.train_set).maps
    p_n2 = _move_probs(trained3, maps, maps)[..., 1].mean()
    print(f"X3.4 P(n2) on identical pairs {float(p_n2):.3f}")
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
