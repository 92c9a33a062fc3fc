"""Each local learning rule against values worked out by hand from its equation."""
import pytest
import torch

from neuroimagery.nn import AllToAll, Delta, Hebbian, Kohonen, QLearning, SupervisedKohonen


def test_hebbian_outstar_by_hand():
    # eq. 4.2 with i presynaptic: dw_ji = eta * x_i * (y_j - w_ji)
    W = torch.tensor([[[0.1, 0.2], [0.3, 0.4], [0.0, 0.5]]])  # (P=1, out=3, in=2)
    x = torch.tensor([[[1.0, 0.5]]])
    y = torch.tensor([[[1.0, 0.0, 0.2]]])
    d = Hebbian(0.5, "outstar").delta(W, pre=x, post=y).tensor()
    expected = torch.tensor([[[0.5 * 1.0 * (1.0 - 0.1), 0.5 * 0.5 * (1.0 - 0.2)],
                              [0.5 * 1.0 * (0.0 - 0.3), 0.5 * 0.5 * (0.0 - 0.4)],
                              [0.5 * 1.0 * (0.2 - 0.0), 0.5 * 0.5 * (0.2 - 0.5)]]])
    assert torch.allclose(d, expected)


def test_hebbian_instar_by_hand():
    # i postsynaptic: dw_ji = eta * y_j * (x_i - w_ji)
    W = torch.tensor([[[0.1, 0.2], [0.3, 0.4]]])
    x = torch.tensor([[[1.0, 0.5]]])
    y = torch.tensor([[[0.0, 2.0]]])
    d = Hebbian(0.1, "instar").delta(W, pre=x, post=y).tensor()
    expected = torch.tensor([[[0.0, 0.0], [0.1 * 2 * (1.0 - 0.3), 0.1 * 2 * (0.5 - 0.4)]]])
    assert torch.allclose(d, expected)


def test_hebbian_outstar_converges_to_association():
    c = AllToAll(4, 3, init="zeros", rules=Hebbian(0.3))
    x = torch.tensor([[0.0, 1.0, 0.0, 0.0]])
    y = torch.tensor([[0.2, 0.9, 0.1]])
    for _ in range(100):
        c.learn(x, y)
    assert torch.allclose(c(x), y, atol=1e-4)


def test_delta_rule_by_hand():
    W = torch.zeros(1, 2, 3)
    x = torch.tensor([[[1.0, 0.0, 2.0]]])
    a = torch.tensor([[[0.5, 0.0]]])
    t = torch.tensor([[[1.0, -1.0]]])
    d = Delta(0.1).delta(W, pre=x, post=a, target=t).tensor()
    expected = 0.1 * torch.tensor([[[0.5, 0.0, 1.0], [-1.0, 0.0, -2.0]]])
    assert torch.allclose(d, expected)


def test_delta_rule_learns_linear_map():
    torch.manual_seed(0)
    M = torch.randn(3, 5)
    c = AllToAll(5, 3, init="zeros", rules=Delta(0.05))
    X = torch.randn(200, 5)
    for _ in range(30):
        for x in X.split(1):
            c.learn(x, c(x), target=x @ M.T)
    assert torch.allclose(c.weight[0], M, atol=1e-3)


def test_kohonen_step_by_hand():
    grid = torch.tensor([[0.0], [1.0], [2.0]])
    W = torch.tensor([[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]])
    x = torch.tensor([[[1.0, 0.0]]])
    rule = Kohonen(eta=0.5, sigma=1.0, iterations=10, eta_final=0.5, sigma_final=1.0)
    d = rule.delta(W, pre=x, bmu=torch.tensor([1]), grid=grid, t=0).tensor()
    import math
    th = [math.exp(-0.5), 1.0, math.exp(-0.5)]
    expected = torch.stack([0.5 * th[k] * (x[0, 0] - W[0, k]) for k in range(3)]).unsqueeze(0)
    assert torch.allclose(d, expected)


def test_kohonen_schedule_decays():
    rule = Kohonen(eta=0.5, sigma=4.0, iterations=101, eta_final=0.05, sigma_final=0.5)
    e0, s0 = rule.schedule(0)
    e1, s1 = rule.schedule(100)
    em, sm = rule.schedule(50)
    assert float(e0) == pytest.approx(0.5) and float(e1) == pytest.approx(0.05)
    assert float(s0) == pytest.approx(4.0) and float(s1) == pytest.approx(0.5)
    assert float(em) == pytest.approx((0.5 * 0.05) ** 0.5, rel=1e-5)


def test_supervised_kohonen_forces_winner_and_normalises():
    grid = torch.tensor([[0.0], [1.0]])
    W = torch.tensor([[[0.5, 0.5], [0.2, 0.8]]])
    x = torch.tensor([[[1.0, 0.0]]])
    rule = SupervisedKohonen(eta=0.5, sigma=0.01)  # neighbourhood reaches the winner only
    d = rule.delta(W, pre=x, bmu=torch.tensor([1]), grid=grid).tensor()
    new = W + d
    # winner 1 moves halfway to x: (0.6, 0.4), already sums to 1; unit 0 unchanged
    assert torch.allclose(new, torch.tensor([[[0.5, 0.5], [0.6, 0.4]]]))
    W2 = torch.tensor([[[1.0, 1.0], [2.0, 2.0]]])
    new2 = W2 + rule.delta(W2, pre=x, bmu=torch.tensor([0]), grid=grid)
    assert torch.allclose(new2.sum(-1), torch.ones(1, 2))


@pytest.mark.parametrize("form,expected_err", [("standard", 1.0 + 0.8 * 2.0 - 0.5), ("printed", (1.0 - 0.8 * 2.0) - 0.5)])
def test_qlearning_by_hand(form, expected_err):
    # q = W x; prev input one-hot state 0 -> q_win = W[a=1, 0] = 0.5; next input state 1 -> qMax = 2.0
    W = torch.tensor([[[0.0, 1.0], [0.5, 2.0]]])  # (P, actions=2, inputs=2)
    x_prev = torch.tensor([[[1.0, 0.0]]])
    x_next = torch.tensor([[[0.0, 1.0]]])
    rule = QLearning(eta=0.1, gamma=0.8, form=form)
    d = rule.delta(W, pre=x_prev, action=torch.tensor([[1]]), reward=torch.tensor([[1.0]]), next_pre=x_next).tensor()
    expected = torch.zeros_like(W)
    expected[0, 1, 0] = 0.1 * expected_err
    assert torch.allclose(d, expected)


def test_qlearning_terminal_has_no_bootstrap():
    W = torch.tensor([[[0.0, 1.0], [0.5, 2.0]]])
    rule = QLearning(eta=1.0, gamma=0.8)
    d = rule.delta(W, pre=torch.tensor([[[1.0, 0.0]]]), action=torch.tensor([[1]]), reward=torch.tensor([[1.0]]),
                   next_pre=torch.tensor([[[0.0, 1.0]]]), done=torch.tensor([[True]])).tensor()
    assert d[0, 1, 0].item() == pytest.approx(1.0 - 0.5)


@pytest.mark.parametrize("make", [lambda: Hebbian(-0.1), lambda: Hebbian(0.1, form="sideways"), lambda: Delta(float("nan")),
                                  lambda: Kohonen(eta=0.0), lambda: QLearning(gamma=1.5), lambda: QLearning(form="x")])
def test_bad_rule_parameters_raise(make):
    with pytest.raises(ValueError):
        make()


def test_learning_step_changes_weights_only_in_train_mode():
    c = AllToAll(3, 2, rules=Hebbian(0.5))
    x, y = torch.ones(1, 3), torch.ones(1, 2)
    before = c.weight.clone()
    c.eval()
    with pytest.warns(UserWarning, match=r"eval\(\) mode"):
        c.learn(x, y)
    assert torch.equal(c.weight, before)
    c.train()
    c.learn(x, y)
    assert not torch.equal(c.weight, before)


def test_two_rules_add_independently_of_order():
    x, y = torch.rand(1, 4, 3), torch.rand(1, 4, 2)
    a = AllToAll(3, 2, seed=1, rules=[Hebbian(0.1), Hebbian(0.2, "instar")])
    b = AllToAll(3, 2, seed=1, rules=[Hebbian(0.2, "instar"), Hebbian(0.1)])
    a.learn(x, y)
    b.learn(x, y)
    assert torch.allclose(a.weight, b.weight, atol=1e-7)


@pytest.mark.parametrize("rule,kind", [(lambda: Hebbian(0.3), "h"), (lambda: Hebbian(0.3, "instar", "mean"), "h"),
                                       (lambda: Delta(0.2), "d")])
def test_in_place_update_equals_computed_change(rule, kind):
    x, y, t = torch.rand(2, 5, 6), torch.rand(2, 5, 4), torch.rand(2, 5, 4)
    a = AllToAll(6, 4, participants=2, seed=3, rules=rule())
    b = AllToAll(6, 4, participants=2, seed=3, rules=rule())
    kw = {"target": t} if kind == "d" else {}
    assert a.learn(x, y, **kw) is None  # fast in-place path
    d = b.learn(x, y, return_delta=True, **kw)
    assert d is not None and d.abs().sum() > 0
    assert torch.allclose(a.weight, b.weight, atol=1e-6)


def test_subclass_overriding_delta_is_not_bypassed():
    class Doubled(Hebbian):
        def delta(self, weight, **kw):
            return 2 * super().delta(weight, **kw)

    x, y = torch.rand(1, 2, 3), torch.rand(1, 2, 2)
    a = AllToAll(3, 2, seed=0, rules=Doubled(0.1))
    b = AllToAll(3, 2, seed=0, rules=Hebbian(0.1))
    w0 = a.weight.clone()
    a.learn(x, y)
    b.learn(x, y)
    assert torch.allclose(a.weight - w0, 2 * (b.weight - w0), atol=1e-6)


@pytest.mark.parametrize("rules", [Hebbian(0.1), Delta(0.1), [Hebbian(0.1)]])
def test_one_to_one_refuses_rules_and_multiplies_element_wise(rules):
    from neuroimagery.nn import OneToOne

    with pytest.raises(ValueError, match="OneToOne is a fixed element-wise gain; it has no learning rule"):
        OneToOne(3, participants=2, rules=rules)
    o = OneToOne(3, participants=2, value=2.0)
    w = torch.tensor([[[0.5, 2.0, -1.0]], [[3.0, 0.0, 1.5]]])  # (P=2, 1, n=3): one gain per unit
    o.weight.copy_(w)
    x = torch.rand(2, 4, 3)
    assert torch.allclose(o(x), x * w)
    assert o.learn(x, x) is None and torch.equal(o.weight, w)  # no rule: learning changes nothing
