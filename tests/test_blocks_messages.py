"""Blocks explain themselves to a user who builds a model from them: mismatched dtypes are handled
as docs/architecture.md says (computed in the input's dtype; learning keeps the weights' dtype),
learning in eval() mode warns once, unnamed blocks have names, and 1-D, wrongly batched or integer
inputs get an error naming the block."""
import re
import warnings

import pytest
import torch

from neuroimagery.nn import SOM, AllToAll, BidirectionalSOM, Delta, DynamicField, GainField, Hebbian, HardWired, OneToOne
from neuroimagery.nn.local import LocalConnection
from neuroimagery.nn.seeding import participant_generators


def conns():
    return [AllToAll(5, 3, participants=2, rules=Hebbian(0.1)), OneToOne(5, participants=2)]


@pytest.mark.parametrize("i", [0, 1])
@pytest.mark.parametrize("weights, inputs", [(torch.float64, torch.float32), (torch.float32, torch.float64)])
def test_connection_computes_in_its_inputs_dtype(i, weights, inputs):
    c = conns()[i].to(weights)
    x = torch.rand(2, 4, 5, generator=torch.Generator().manual_seed(0))
    y = c(x.to(inputs))
    assert y.dtype == inputs and c.weight.dtype == weights
    ref = conns()[i].to(inputs)
    ref.weight.copy_(c.weight)
    torch.testing.assert_close(y, ref(x.to(inputs)))


@pytest.mark.parametrize("sequence", [False, True])
def test_learning_with_other_dtype_keeps_the_weights_dtype(sequence):
    c = AllToAll(5, 3, participants=2, rules=Hebbian(0.1))
    ref = AllToAll(5, 3, participants=2, rules=Hebbian(0.1))
    g = torch.Generator().manual_seed(1)
    pre, post = torch.rand(2, 4, 5, generator=g), torch.rand(2, 4, 3, generator=g)
    c.learn(pre.double(), post.double(), sequence=sequence)
    ref.learn(pre, post, sequence=sequence)
    assert c.weight.dtype == torch.float32
    torch.testing.assert_close(c.weight, ref.weight)


def test_delta_sequence_and_som_with_other_dtype():
    c = AllToAll(5, 3, participants=2, rules=Delta(0.1)).double()
    g = torch.Generator().manual_seed(2)
    c.learn(torch.rand(2, 6, 5, generator=g), None, sequence=True, target=torch.rand(2, 6, 3, generator=g))
    assert c.weight.dtype == torch.float64
    som = SOM((3, 3), 4, participants=2).double()
    x = torch.rand(2, 5, 4, generator=g)
    assert som(x).dtype == torch.float32 and som.bmu(x).shape == (2, 5)
    som.step(x[:, 0])
    som.fit(x, iterations=5)
    assert som.weight.dtype == torch.float64


def test_local_connection_and_bidirectional_som_with_other_dtype():
    lc = LocalConnection(3, 1.0, participant_generators(0, 2), rules=Delta(0.1)).double()
    x = (torch.rand(2, 1, 27, generator=torch.Generator().manual_seed(3)) > 0.5).float()
    assert lc.net(x).dtype == torch.float32
    lc.learn(x, target=x)
    assert lc.weight.dtype == torch.float64
    b = BidirectionalSOM(4, 3, 2, participants=2).double()
    assert b(torch.rand(2, 1, 3)).dtype == torch.float64  # a prototype of the map itself


def test_learn_in_eval_mode_warns_once_per_connection():
    a, b = AllToAll(3, 2, rules=Hebbian(0.5), name="C1"), AllToAll(3, 2, rules=Hebbian(0.5))
    x, y = torch.ones(1, 3), torch.ones(1, 2)
    a.eval()
    b.eval()
    with pytest.warns(UserWarning) as rec:
        a.learn(x, y)
        a.learn(x, y, sequence=True)
        b.learn(x, y)
    assert len(rec) == 2 and rec[0].filename == __file__  # once per connection, pointing at the call
    assert str(rec[0].message).startswith("connection 'C1' is in eval() mode: learn() leaves its weights unchanged")
    assert str(rec[1].message).startswith("connection 'AllToAll(3->2)' is in eval() mode")
    lc = LocalConnection(3, 1.0, participant_generators(0, 1), rules=Delta(0.1)).eval()
    with pytest.warns(UserWarning, match="eval"):
        lc.learn(torch.zeros(1, 1, 27), target=torch.zeros(1, 1, 27))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a.train().learn(x, y)  # learning: no warning
        HardWired(torch.eye(3)).eval().learn(x, x)  # no rule: nothing to warn about


def test_unnamed_blocks_have_names():
    assert AllToAll(37, 13).name == "AllToAll(37->13)"
    assert OneToOne(4).name == "OneToOne(4->4)"
    assert HardWired(torch.zeros(2, 3)).name == "HardWired(3->2)"
    assert GainField(3, 4).name == "GainField(3x4)"
    assert SOM((3, 4), 5).name == "SOM(3x4, in=5)"
    assert DynamicField((7,)).name == "DynamicField(7)"
    assert AllToAll(3, 2, name="C1").name == "C1"
    with pytest.raises(ValueError, match=r"connection 'AllToAll\(5->3\)'") as e:
        AllToAll(5, 3, participants=2)(torch.rand(3, 1, 5))
    assert "''" not in str(e.value)


@pytest.mark.parametrize("shape, says", [
    ((5,), r"a 1-D input \(5,\) is one trial of one participant, but the block holds the weights of 2 participants: give \(2, trials, 5\)"),
    ((4, 5), r"a 2-D input \(4, 5\) is 4 trials of one participant, but the block holds the weights of 2 participants"),
    ((3, 4, 5), r"input has 3 participants, the weights 2"),
    ((1, 4, 5), r"input has 1 participant, the weights 2"),
])
def test_inputs_of_other_participants_are_explained(shape, says):
    x = torch.rand(shape)
    for c in conns():
        with pytest.raises(ValueError, match=f"connection {re.escape(repr(c.name))}: " + says):
            c(x)
    with pytest.raises(ValueError, match=r"SOM 'SOM\(3x3, in=5\)': " + says):
        SOM((3, 3), 5, participants=2)(x)
    with pytest.raises(ValueError, match=r"pre of connection 'AllToAll\(5->3\)': " + says):
        conns()[0].learn(x, torch.rand(*shape[:-1], 3))


def test_one_participant_blocks_still_take_1d_and_2d_inputs():
    c = AllToAll(5, 3)
    assert c(torch.rand(5)).shape == (3,) and c(torch.rand(4, 5)).shape == (4, 3)
    shared = HardWired(torch.eye(5))
    assert shared(torch.rand(3, 4, 5)).shape == (3, 4, 5)  # shared weights serve any participants


@pytest.mark.parametrize("dtype", [torch.int64, torch.int32, torch.bool])
def test_integer_inputs_are_refused_naming_the_block(dtype):
    x = torch.ones(2, 4, 5).to(dtype)
    for c in conns():
        with pytest.raises(ValueError, match=rf"input of connection {re.escape(repr(c.name))} has dtype {dtype}: activity must be floating point"):
            c(x)
    with pytest.raises(ValueError, match=rf"pre of connection .* has dtype {dtype}"):
        conns()[0].learn(x, torch.ones(2, 4, 3))
    with pytest.raises(ValueError, match=rf"pre of connection .* has dtype {dtype}"):
        conns()[0].learn(x, torch.ones(2, 4, 3), sequence=True)
    with pytest.raises(ValueError, match=rf"input of SOM .* has dtype {dtype}"):
        SOM((3, 3), 5, participants=2)(x)
    with pytest.raises(ValueError, match=rf"input of DynamicField 'DynamicField\(5\)' has dtype {dtype}"):
        DynamicField((5,))(torch.ones(5).to(dtype))
    with pytest.raises(ValueError, match=rf"input of connection .* has dtype {dtype}"):
        LocalConnection(3, 1.0, participant_generators(0, 2)).net(torch.ones(2, 1, 27).to(dtype))
