"""Decision dynamics: field competition to threshold, leaky competing accumulator, softmax."""
import pytest
import torch

from neuroimagery.nn import DynamicField, LeakyCompetingAccumulator, PopulationMap, softmax_probabilities, softmax_select


def test_field_forms_one_bump_at_strongest_input():
    f = DynamicField((30,), a_exc=0.6, sigma_exc=1.5, a_inh=0.15)
    m = PopulationMap("m", (30,), 0, 29, sigma=1.5)
    s = 0.5 * m.encode(torch.tensor(8.0)) + 0.4 * m.encode(torch.tensor(22.0))
    d = f(s.unsqueeze(0), max_cycles=500)
    assert d.decided.all() and d.winner.item() in (7, 8, 9)
    u = d.state[0]
    for _ in range(300):  # let the competition settle after the decision
        u = f.step(u, s)
    u = u.clamp_min(0)
    active = (u > 0.5 * u.max()).nonzero().flatten()
    assert int(active.max() - active.min()) <= 6  # one compact bump, the rival suppressed
    assert u[18:27].max() == 0.0


def test_field_is_faster_with_stronger_input():
    f = DynamicField((10, 20))
    m = PopulationMap("m", (10, 20), 0, 1, sigma=0.1)
    bump = m.encode(torch.tensor([0.5, 0.5]))
    cycles = [int(f((a * bump).unsqueeze(0)).cycles) for a in (0.3, 0.6, 1.0, 2.0)]
    assert cycles == sorted(cycles, reverse=True) and cycles[0] > cycles[-1]


def test_field_without_input_never_decides():
    d = DynamicField((5,))(torch.zeros(1, 5), max_cycles=50)
    assert not d.decided.any() and d.cycles.item() == 50 and d.winner.item() == -1


def test_lca_picks_stronger_and_is_slower_when_close():
    lca = LeakyCompetingAccumulator(k=0.2, w=0.5, threshold=1.2)
    d = lca(torch.tensor([[1.0, 0.3], [1.0, 0.8], [0.3, 1.0]]), cycles=1000)
    assert d.winner.tolist() == [0, 0, 1]
    assert d.cycles[1] > d.cycles[0]


def test_lca_by_hand_one_cycle():
    lca = LeakyCompetingAccumulator(k=0.2, w=0.5, threshold=10.0, dt=0.1)
    y0 = torch.tensor([[0.4, 0.2]])
    d = lca(torch.tensor([[1.0, 0.5]]), cycles=1, state=y0)
    expected = torch.tensor([[0.4 + 0.1 * (-0.2 * 0.4 - 0.5 * 0.2 + 1.0), 0.2 + 0.1 * (-0.2 * 0.2 - 0.5 * 0.4 + 0.5)]])
    assert torch.allclose(d.state, expected)


def test_lca_state_carries_over_between_calls():
    lca = LeakyCompetingAccumulator()
    I = torch.tensor([[0.9, 0.4]])
    whole = lca(I, cycles=40)
    first = lca(I, cycles=10)
    rest = lca(I, cycles=30, state=first.state, active=~first.decided)
    assert whole.decided.item() == (first.decided | rest.decided).item()
    assert int(whole.cycles) == 10 + int(rest.cycles)


def test_lca_leak_per_element_equals_accumulators_of_that_leak():
    inputs = torch.tensor([[0.9, 0.7], [0.9, 0.7], [0.5, 0.6]])
    leak = torch.tensor([0.5, 1.5, 1.0])
    d = LeakyCompetingAccumulator(2, k=0.5, w=0.5, threshold=1.2, dt=0.1)(inputs, 80, leak=leak)
    for i, k in enumerate(leak.tolist()):
        one = LeakyCompetingAccumulator(2, k=k, w=0.5, threshold=1.2, dt=0.1)(inputs[i:i + 1], 80)
        assert int(one.cycles) == int(d.cycles[i]) and int(one.winner) == int(d.winner[i])
        torch.testing.assert_close(one.state[0], d.state[i])
    assert int(d.cycles[0]) < int(d.cycles[1])  # a larger leak decides later (or not at all)


def test_gain_search_of_many_rows_equals_each_row_searched_alone():
    """smallest_deciding_gain: rows searched together (several leaks, both answers, one call) get
    the gains each row gets alone, bit for bit; rows favouring the other unit or empty get inf."""
    from neuroimagery.nn.decision import smallest_deciding_gain

    g = torch.Generator().manual_seed(7)
    ev = torch.rand(12, 2, generator=g)
    ev[3] = 0.0
    leak = 0.5 + torch.rand(12, generator=g)
    answer = torch.arange(12) % 2
    lca = LeakyCompetingAccumulator(2, k=0.5, w=0.5, threshold=1.2, dt=0.1)
    together = smallest_deciding_gain(lca, ev, 10, answer=answer, leak=leak)
    for i in range(12):
        alone = smallest_deciding_gain(lca, ev[i:i + 1], 10, answer=int(answer[i]), leak=leak[i:i + 1])
        assert torch.equal(alone, together[i:i + 1]), i
    favoured = ev.gather(1, answer.unsqueeze(1)).squeeze(1) > ev.gather(1, (1 - answer).unsqueeze(1)).squeeze(1)
    assert torch.isinf(together[~favoured]).all() and torch.isfinite(together[favoured]).all()


def test_softmax_selection_frequencies():
    x = torch.tensor([[1.0, 0.0, 0.5]]).expand(20000, -1)
    idx = softmax_select(x, 0.5, generators=[torch.Generator().manual_seed(0)])
    freq = torch.bincount(idx, minlength=3).float() / idx.numel()
    p = softmax_probabilities(x[0], 0.5)
    assert torch.allclose(freq, p, atol=0.015)


def test_bad_decision_parameters():
    with pytest.raises(ValueError, match="temperature"):
        softmax_probabilities(torch.zeros(3), 0.0)
    with pytest.raises(ValueError, match="threshold"):
        LeakyCompetingAccumulator(threshold=-1)
    with pytest.raises(ValueError, match="input"):
        DynamicField((4,))(torch.zeros(2, 5))
