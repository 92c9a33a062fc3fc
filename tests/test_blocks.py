"""Maps and connections: encoding, batching, autograd drop-in, state_dict, bad inputs."""
import pytest
import torch

from neuroimagery.nn import AllToAll, GainField, HardWired, Hebbian, OneToOne, PopulationMap, participant_generators


def test_map_encode_decode_roundtrip_1d_and_2d():
    m = PopulationMap("angle", (37,), -90, 90, sigma=10)
    v = torch.tensor([-72.0, -5.0, 33.0, 60.0])
    assert torch.allclose(m.decode(m.encode(v)), v, atol=0.5)
    assert m.decode(m.encode(v), "argmax").sub(v).abs().max() <= 2.5
    m2 = PopulationMap("posture", (31, 105), (0, 0), (1, 1), sigma=0.05)
    v2 = torch.tensor([[0.3, 0.7], [0.5, 0.5]])
    a = m2.encode(v2)
    assert a.shape == (2, 31, 105)
    assert torch.allclose(m2.decode(a), v2, atol=0.01)


def test_map_bump_value_by_hand():
    m = PopulationMap("m", (3,), 0, 2, sigma=1.0)
    a = m.encode(torch.tensor(0.0))
    assert torch.allclose(a, torch.exp(-torch.tensor([0.0, 1.0, 4.0]) / 2))


def test_feedforward_by_hand_and_transfer():
    c = AllToAll(2, 2, init="zeros", transfer_fn="sigmoid")
    c.weight.copy_(torch.tensor([[[1.0, -1.0], [0.5, 2.0]]]))
    x = torch.tensor([[1.0, 2.0]])
    assert torch.allclose(c(x), torch.sigmoid(torch.tensor([[-1.0, 4.5]])))
    with pytest.raises(ValueError, match="transfer"):
        AllToAll(2, 2, transfer_fn="softplusplus")


def test_batched_participants_equal_solo_runs():
    P = 3
    x = torch.rand(P, 5, 8, generator=torch.Generator().manual_seed(0))
    y = torch.rand(P, 5, 4, generator=torch.Generator().manual_seed(1))
    batch = AllToAll(8, 4, generators=participant_generators(7, P), rules=Hebbian(0.2))
    for _ in range(3):
        batch.learn(x, y)
    for p in range(P):
        solo = AllToAll(8, 4, generators=participant_generators(7, [p]), rules=Hebbian(0.2))
        for _ in range(3):
            solo.learn(x[p:p + 1], y[p:p + 1])
        assert torch.allclose(solo.weight[0], batch.weight[p], atol=1e-6)
        assert torch.allclose(solo(x[p]), batch(x)[p], atol=1e-6)


def test_drop_in_between_linear_layers_with_autograd():
    net = torch.nn.Sequential(torch.nn.Linear(6, 10), AllToAll(10, 4, rules=Hebbian(0.1)), torch.nn.Linear(4, 1))
    out = net(torch.rand(5, 6)).sum()
    out.backward()
    assert net[0].weight.grad is not None and net[0].weight.grad.abs().sum() > 0
    assert not net[1].weight.requires_grad
    # the block adds no parameters: exactly the two Linear layers' weights and biases
    assert sum(p.numel() for p in net.parameters()) == (6 * 10 + 10) + (4 * 1 + 1)
    assert len(list(net[1].parameters())) == 0


def test_state_dict_roundtrip():
    a = AllToAll(5, 3, participants=2, seed=1)
    b = AllToAll(5, 3, participants=2, seed=2)
    assert not torch.equal(a.weight, b.weight)
    b.load_state_dict(a.state_dict())
    assert torch.equal(a.weight, b.weight)


def test_one_to_one_hardwired_gainfield():
    o = OneToOne(3, value=2.0)
    assert torch.allclose(o(torch.tensor([[1.0, 2.0, 3.0]])), torch.tensor([[2.0, 4.0, 6.0]]))
    flip = HardWired.permutation(torch.tensor([2, 1, 0]))
    assert torch.equal(flip(torch.tensor([[1.0, 2.0, 3.0]])), torch.tensor([[3.0, 2.0, 1.0]]))
    g = GainField(2, 3)(torch.tensor([1.0, 2.0]), torch.tensor([1.0, 0.0, 3.0]))
    assert torch.equal(g, torch.tensor([[1.0, 0.0, 3.0], [2.0, 0.0, 6.0]]))


@pytest.mark.parametrize("bad,match", [(torch.rand(2, 7), "shape"), (torch.full((2, 5), float("nan")), "NaN"),
                                       ([1.0, 2.0], "Tensor")])
def test_bad_inputs_name_the_argument(bad, match):
    with pytest.raises(ValueError, match=match):
        AllToAll(5, 3)(bad)


def test_participant_mismatch_is_reported():
    c = AllToAll(5, 3, participants=2)
    with pytest.raises(ValueError, match="participants"):
        c(torch.rand(3, 1, 5))


def test_intra_op_threads_sets_caps_and_restores():
    from neuroimagery.nn.functional import intra_op_threads

    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with intra_op_threads(1):
            assert torch.get_num_threads() == 1
        with intra_op_threads(3, cap=True):
            assert torch.get_num_threads() == 2
        with pytest.raises(RuntimeError):
            with intra_op_threads(1):
                raise RuntimeError("inside")
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
