"""Experiment 4 contracts X4.1-X4.5, X4.11, X4.13 and X4.14 (docs/contracts.md): the supervised
Kohonen step, the posture maps C16/C17, the gain field and PMCm, the wrist signal in PPCp, the
stochastic draw of the move and the percept that varies between looks."""
import torch
from support_ch6 import assert_looks_vary, assert_supervised_rate, item_rows

from neuroimagery.experiments.exp4 import protocol as exp4
from neuroimagery.nn.functional import gain_field, softmax_probabilities, softmax_select


def test_x4_1_supervised_step_moves_at_the_stated_rate(trained4):
    m = trained4.model
    assert_supervised_rate(trained4, (m.c16, m.c17), trained4.e.ppc.angles, trained4.e.posture.eta, "X4.1")


def test_x4_2_posture_maps_read_the_trained_posture(trained4):
    m, bank = trained4.model, trained4.bank(trained4.e.train_set)
    labels = bank.angle_labels(trained4.e.ppc.angles)
    x = bank.maps.unsqueeze(0).expand(m.participants, -1, -1)
    for som in (m.c16, m.c17):
        acc = (m.posture(som, x) == labels).float().mean(-1)
        print(f"X4.2 {som.name} {acc.tolist()}")
        assert (acc >= 0.95).all()


def _contrast(m, maps):
    pot = torch.bmm(maps.unsqueeze(0).expand(m.participants, -1, -1), m.c16.weight.transpose(1, 2))
    mx = pot.max(-1).values
    return float(((mx - pot.mean(-1)) / mx.clamp_min(1e-12)).mean())


def test_x4_3_hard_shapes_give_flatter_potentials(trained4):
    e = trained4.e
    A, C = trained4.bank(e.train_set).maps, trained4.bank(e.gen2_set).maps
    a, c = _contrast(trained4.model, A), _contrast(trained4.model, C)
    untrained = exp4._model(trained4.cfg, [0, 1])  # the same participants' initial weights
    a0, c0 = _contrast(untrained, A), _contrast(untrained, C)
    print(f"X4.3 PPCpA contrast: set A {a:.4f}, set C {c:.4f}; untrained: set A {a0:.4f}, set C {c0:.4f}")
    assert a > c and a - c > a0 - c0


def _probs(m, tau, ppct_unit, ppcp_unit):
    nu = len(m.p.ppc.angles)
    pt, pp = m.ppc.encode(ppct_unit.float()), m.ppc.encode(ppcp_unit.float())
    return softmax_probabilities(m.pmcm_input(gain_field(pt, pp).reshape(-1, nu * nu)), tau)


def test_x4_4_gain_field_stays_at_a_match_and_turns_toward_the_target(trained4):
    m, tau = trained4.model, trained4.e.selection.tau
    nu = len(trained4.e.ppc.angles)
    units = torch.arange(nu)
    p_same = _probs(m, tau, units, units)[:, 1]
    t, c = torch.meshgrid(units, units, indexing="ij")
    off = t != c
    pr = _probs(m, tau, t[off], c[off])
    # PPC units increase with angle; target above the current posture -> turn counter-clockwise (Ml)
    toward = torch.where(t[off] > c[off], pr[:, 0], pr[:, 2])
    print(f"X4.4 P(Ms) at a match min {float(p_same.min()):.4f}; P(toward) min {float(toward.min()):.4f}")
    same = _probs(m, tau, units, units)
    assert bool((same.argmax(-1) == 1).all())
    assert bool((torch.where(t[off] > c[off], pr[:, 0], pr[:, 2]) >= pr.max(-1).values).all())


def test_x4_5_first_move_turns_toward_the_target(trained4):
    m, bank, e = trained4.model, trained4.bank(trained4.e.train_set), trained4.e
    rows = item_rows(bank)
    tg, rt, up = [], [], []
    for i, o, a, ap in rows:
        for j, o2, b, ap2 in rows:
            if o2 == o and ap2 == ap and a != b:
                tg.append(i), rt.append(j), up.append(a > b)
    P = m.participants
    target = bank.maps[tg].unsqueeze(0).expand(P, -1, -1)
    pocp = m.forward_step(bank.maps[rt].unsqueeze(0).expand(P, -1, -1), torch.ones(P, len(rt), dtype=torch.long))
    pr = _probs(m, e.selection.tau, m.posture(m.c17, target).reshape(-1), m.posture(m.c16, pocp).reshape(-1))
    u = torch.tensor(up).repeat(P)
    toward = torch.where(u, pr[:, 0], pr[:, 2])
    share = float(toward.mean())
    print(f"X4.5 P(first move toward the target) {share:.3f}")
    assert share >= 0.8


def test_x4_11_wrist_signal_in_ppcp(trained4):
    m = trained4.model
    nu = len(trained4.e.ppc.angles)
    j = torch.arange(nu)
    match = m.ppcp_code(j, "match")
    mis = m.ppcp_code(j, "mismatch")
    assert (match.argmax(-1) == j).all()
    assert (mis[j, j] >= 0.5).all() and (mis[j, nu - 1 - j] >= 0.5).all()
    g = torch.Generator().manual_seed(0)
    for prop in ("none", "match", "mismatch"):
        noisy = m.ppcp_code(j.repeat(100), prop, torch.rand(100 * nu, nu, generator=g))
        assert noisy.min() >= 0.0 and noisy.max() <= 1.0


def test_x4_13_the_move_is_a_stochastic_draw(trained4):
    m, tau = trained4.model, trained4.e.selection.tau
    nu = len(trained4.e.ppc.angles)
    units = torch.arange(nu)
    pt, pp = m.ppc.encode(units.float()), m.ppc.encode(units.roll(1).float())
    am = m.pmcm_input(gain_field(pt, pp).reshape(-1, nu * nu))[:2]  # two fixed PMCm inputs
    n = 20000
    g = torch.Generator().manual_seed(0)
    draws = softmax_select(am.repeat_interleave(n, 0), tau, uniforms=torch.rand(2 * n, generator=g)).reshape(2, n)
    freq = torch.stack([(draws == k).float().mean(1) for k in range(3)], -1)
    gap = float((freq - softmax_probabilities(am, tau)).abs().max())
    p_other = 1 - _probs(m, tau, units, units)[:, 1]
    print(f"X4.13 (a) largest gap between draw frequency and eq. 6.11 {gap:.4f}; (b) P(not Ms) at a match {p_other.tolist()}")
    assert gap <= 0.01
    assert bool((p_other >= 0.005).all())


def test_x4_14_the_percept_varies_between_looks(trained4):
    m = trained4.model
    assert_looks_vary(trained4, (m.c16, m.c17), trained4.e.ppc.angles, lambda out: out, "X4.14")
