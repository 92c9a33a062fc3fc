"""GatedHebbian (repeated, gated outstar) and QLearning's in-place path against the plain rules."""
import pytest
import torch

from neuroimagery.nn.connections import AllToAll
from neuroimagery.nn.rules import GatedHebbian, Hebbian, QLearning


def _plain_outstar(w, x, y, eta, steps):
    """``steps`` plain outstar Hebbian steps (eq. 4.2-4.3), one pattern each."""
    c = AllToAll(w.shape[2], w.shape[1], init="zeros", rules=Hebbian(eta, "outstar"))
    c.weight.copy_(w)
    for _ in range(steps):
        c.learn(pre=x.reshape(1, -1), post=y.reshape(1, -1))
    return c.weight


@pytest.mark.parametrize("binary", [True, False])
def test_gated_hebbian_equals_repeated_plain_steps_on_the_gated_unit(binary):
    g = torch.Generator().manual_seed(3)
    n_in, n_out, eta, k = 40, 5, 0.2, 7
    x = (torch.rand(n_in, generator=g) < 0.4).float() if binary else torch.rand(n_in, generator=g)
    w0 = torch.rand(1, n_out, n_in, generator=g)
    y = torch.zeros(n_out)
    y[2] = 0.3
    c = AllToAll(n_in, n_out, init="zeros", rules=GatedHebbian(eta))
    c.weight.copy_(w0)
    gate = torch.zeros(1, n_out)
    gate[0, 2] = 1.0
    c.learn(pre=x.reshape(1, -1), post=y.reshape(1, -1), gate=gate, repeats=k)
    plain = _plain_outstar(w0, x, y, eta, k)
    assert torch.allclose(c.weight[0, 2], plain[0, 2], atol=1e-6)  # the gated unit: k plain steps
    assert torch.equal(c.weight[0, [0, 1, 3, 4]], w0[0, [0, 1, 3, 4]])  # the others keep their weights
    # the change delta() computes, added densely, equals the one the connection applied in place
    d = GatedHebbian(eta).delta(w0.clone(), x.reshape(1, 1, -1), y.reshape(1, 1, -1), gate=gate, repeats=k)
    assert torch.equal(w0, w0.clone()) and torch.allclose(w0 + d, c.weight, atol=1e-6)


def test_gated_hebbian_refuses_bad_gates_and_batches():
    rule = GatedHebbian(0.1)
    w = torch.zeros(1, 2, 3)
    with pytest.raises(ValueError, match="gate"):
        rule.delta(w, torch.ones(1, 1, 3), torch.ones(1, 1, 2), gate=torch.full((1, 2), 0.5))
    with pytest.raises(ValueError, match="one pattern"):
        rule.delta(w, torch.ones(1, 2, 3), torch.ones(1, 2, 2))


def _eq_7_1_by_hand(w, x0, unit, reward, x1, done, eta, gamma, sign):
    w = w.clone()
    q_max = 0.0 if done else float((w @ x1).max())
    err = reward + sign * gamma * q_max - float(w[unit] @ x0)
    w[unit] += eta * err * x0
    return w


@pytest.mark.parametrize("form,sign", [("standard", 1.0), ("printed", -1.0)])
@pytest.mark.parametrize("done", [False, True])
def test_q_learning_in_place_equals_its_delta_and_eq_7_1(form, sign, done):
    g = torch.Generator().manual_seed(5)
    x0 = (torch.rand(30, generator=g) < 0.3).float()
    x1 = (torch.rand(30, generator=g) < 0.3).float()
    w0 = torch.rand(1, 4, 30, generator=g) * 0.1
    rule = QLearning(0.05, 0.8, form)
    kw = dict(action=torch.tensor([[1]]), reward=torch.tensor([[1.0]]), next_pre=x1.reshape(1, 1, -1),
              done=torch.tensor([[done]]))
    c = AllToAll(30, 4, init="zeros", rules=rule)
    c.weight.copy_(w0)
    c.learn(pre=x0.reshape(1, -1), **kw)  # the in-place path
    via_delta = w0 + rule.delta(w0, x0.reshape(1, 1, -1), **kw)
    hand = _eq_7_1_by_hand(w0[0], x0, 1, 1.0, x1, done, 0.05, 0.8, sign)
    assert torch.allclose(c.weight, via_delta, atol=1e-7)
    assert torch.allclose(c.weight[0], hand, atol=1e-7)
    assert torch.equal(c.weight[0, [0, 2, 3]], w0[0, [0, 2, 3]])


def test_q_learning_batch_changes_are_computed_at_the_same_weights():
    g = torch.Generator().manual_seed(6)
    pre = torch.rand(2, 3, 8, generator=g)
    nxt = torch.rand(2, 3, 8, generator=g)
    w0 = torch.rand(2, 4, 8, generator=g)
    kw = dict(action=torch.tensor([[0, 1, 0], [3, 3, 2]]), reward=torch.rand(2, 3, generator=g), next_pre=nxt)
    for reduction in ("sum", "mean"):
        rule = QLearning(0.1, 0.8, reduction=reduction)
        w = w0.clone()
        rule.delta(w, pre, **kw).apply_(w)  # the change applied in place, as a connection does
        assert torch.allclose(w, w0 + rule.delta(w0, pre, **kw), atol=1e-6)


def test_gated_hebbian_and_q_learning_learn_on_meta_and_agree_off_host(monkeypatch):
    """Off the host (meta here; a GPU alike) the rules form the same change with tensor operations."""
    import neuroimagery.nn.rules as rules

    c = AllToAll(8, 3, init="zeros", rules=GatedHebbian(0.2)).to("meta")
    c.learn(pre=torch.ones(1, 8, device="meta"), post=torch.ones(1, 3, device="meta"),
            gate=torch.ones(1, 3, device="meta"), repeats=3)
    assert c.weight.device.type == "meta"
    g = torch.Generator().manual_seed(7)
    x = (torch.rand(1, 1, 8, generator=g) < 0.5).float()
    w0 = torch.rand(1, 3, 8, generator=g)
    y, gate = torch.tensor([[[0.0, 0.4, 0.0]]]), torch.tensor([[0.0, 1.0, 0.0]])
    host, off = w0.clone(), w0.clone()
    GatedHebbian(0.2).delta(host, x, y, gate=gate, repeats=4).apply_(host)
    monkeypatch.setattr(rules, "_on_host", lambda w: False)
    GatedHebbian(0.2).delta(off, x, y, gate=gate, repeats=4).apply_(off)
    assert torch.allclose(host, off, atol=1e-6)
    q_host, q_off = w0.clone(), w0.clone()
    kw = dict(action=torch.tensor([[2]]), reward=torch.tensor([[1.0]]), next_pre=x.clone())
    monkeypatch.undo()
    QLearning(0.1).delta(q_host, x, **kw).apply_(q_host)
    monkeypatch.setattr(rules, "_on_host", lambda w: False)
    QLearning(0.1).delta(q_off, x, **kw).apply_(q_off)
    assert torch.allclose(q_host, q_off, atol=1e-6)
