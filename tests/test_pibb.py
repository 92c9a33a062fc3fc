"""PI^BB (eq. 7.6-7.8): sampling, softmax weights, weighted mean, immutability, convergence."""
import pytest
import torch

from neuroimagery.motor.pibb import PIBB, event_costs, graded_costs


def test_sample_statistics():
    d = PIBB.from_sigma(torch.tensor([1.0, -2.0, 0.0]), torch.tensor([0.1, 1.0, 3.0]), n_samples=20000)
    s = d.sample(torch.Generator().manual_seed(0))
    assert s.shape == (20000, 3)
    assert torch.allclose(s.mean(0), d.mean, atol=0.05)
    assert torch.allclose(s.std(0), torch.tensor([0.1, 1.0, 3.0]), rtol=0.03)


def test_weights_are_eq_7_7_and_update_is_eq_7_8():
    d = PIBB.from_sigma(torch.zeros(2), 1.0, n_samples=3, temperature=0.5, decay=0.8)
    samples = torch.tensor([[1.0, 0.0], [0.0, 1.0], [2.0, 2.0]])
    costs = torch.tensor([0.0, 1.0, 2.0])
    e = torch.exp(-costs / 0.5)
    p = e / e.sum()
    assert torch.allclose(d.weights(costs), p)
    new = d.update(samples, costs)
    assert torch.allclose(new.mean, p @ samples)
    assert torch.allclose(new.covariance, 0.8 * torch.eye(2))
    # immutable: the old distribution is untouched
    assert torch.equal(d.mean, torch.zeros(2)) and torch.equal(d.covariance, torch.eye(2))


def test_flat_costs_average_the_samples():
    samples = torch.tensor([[1.0, 0.0], [0.0, 3.0], [2.0, 0.0]])
    for cost in (0.0, 1.0):
        costs = torch.full((3,), cost)
        avg = PIBB.from_sigma(torch.zeros(2), 1.0, n_samples=3, decay=0.8).update(samples, costs)
        assert torch.allclose(avg.mean, torch.tensor([1.0, 1.0]))  # uniform weights: the plain mean
        assert torch.allclose(avg.covariance, 0.8 * torch.eye(2))
    costs = torch.tensor([1.0, 0.0, 1.0])
    a = PIBB.from_sigma(torch.zeros(2), 1.0, n_samples=3, decay=0.8).update(samples, costs)
    assert a.mean[1] > 2.5  # the successful sample dominates


def test_minimises_a_quadratic():
    target = torch.tensor([1.0, -1.0, 0.5])
    d = PIBB.from_sigma(torch.zeros(3), 1.0, n_samples=10, temperature=0.1, decay=0.95)
    gen = torch.Generator().manual_seed(0)
    for _ in range(60):
        s = d.sample(gen)
        c = ((s - target) ** 2).sum(1)
        d = d.update(s, c / c.max())
    assert (d.mean - target).norm() < 0.15


def test_errors():
    with pytest.raises(ValueError, match="NaN"):
        PIBB.from_sigma(torch.tensor([0.0, float("nan")]), 1.0)
    d = PIBB.from_sigma(torch.zeros(2), 1.0)
    with pytest.raises(ValueError, match="costs"):
        d.update(torch.zeros(3, 2), torch.tensor([0.0, float("nan"), 1.0]))
    with pytest.raises(ValueError, match="temperature"):
        PIBB.from_sigma(torch.zeros(2), 1.0, temperature=0.0)


def test_event_costs():
    class O:
        def __init__(self, f, b=False):
            self.f, self.blew_up = f, b

        def fired(self, name):
            return self.f

    assert event_costs([O(True), O(False), O(True, True)], "south").tolist() == [0.0, 1.0, 1.0]


def test_graded_costs_rank_misses():
    from types import SimpleNamespace as NS

    def out(events, disp, gap, blew=False):
        names = ("retrieve", "touch", "south", "north", "west", "east")
        return NS(fired=lambda e: e in events, toy_displacement=disp, min_gap=gap, blew_up=blew)

    outs = [out({"south"}, (-0.05, 0.0), 0.0), out(set(), (-0.01, 0.0), 0.0), out(set(), (0.0, 0.0), 0.0),
            out(set(), (0.0, 0.0), 0.05), out(set(), (0.0, 0.0), 0.5), out({"south"}, (-0.05, 0.0), 0.0, blew=True)]
    c = graded_costs(outs, "south", move_threshold=0.02)
    # fired = 0; half-way pushed = 1 - 0.6*0.5 - 0.3 = 0.4; touched but not moved = 0.7;
    # 5 cm away = 0.85; far = 1; blown up = 1
    assert torch.allclose(c, torch.tensor([0.0, 0.4, 0.7, 0.85, 1.0, 1.0]))
    # moving the wrong way earns nothing
    assert graded_costs([out(set(), (0.05, 0.0), 0.5)], "south")[0] == 1.0
    with pytest.raises(ValueError, match="unknown event"):
        graded_costs(outs, "up")
