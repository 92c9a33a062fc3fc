"""The building blocks on any device and dtype, through pickle and under torch.compile.

Every block is run by one function ``run(module, to)`` that feeds it inputs made on the CPU in
float32 and passed through ``to`` (to the device and dtype under test), and returns what it
computed: outputs, and the weights after learning. The same function on the same module
built on the CPU in float32 is the reference.
"""
from __future__ import annotations

import copy
import pickle

import pytest
import torch
from torch.testing import assert_close

from neuroimagery.motor.dmp import DMP
from neuroimagery.nn import (AllToAll, BidirectionalSOM, Delta, DynamicField, GainField, Hebbian, HardWired,
                             LeakyCompetingAccumulator, OneToOne, PopulationMap, QLearning, SOM, functional,
                             participant_generators, seeding)
from neuroimagery.nn.som import ORDER_STREAM

CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
# float64 (or another device) against the float32 CPU reference: the same arithmetic, so they part
# only by float32 rounding (eps 1.2e-7) carried through a few hundred steps at most; 1e-4 relative
# (about 1000 eps) and 1e-5 absolute (for entries near 0) keep a wide margin above that
FLOAT32_REF = dict(rtol=1e-4, atol=1e-5)


def _rand(*shape, seed=0):
    return torch.rand(*shape, generator=torch.Generator().manual_seed(seed))


def _gen(seed=0):
    return torch.Generator().manual_seed(seed)


# ---------------------------------------------------------------------- the blocks and their runs
def run_hebbian(m, to):
    x, y = to(_rand(2, 3, 6)), to(_rand(2, 3, 5, seed=1))
    out = m(x)
    m.learn(pre=x, post=y)  # one rule: updated in place
    return {"forward": out, "weight": m.weight, "forward_after": m(x)}


def run_two_rules(m, to):
    x, y = to(_rand(2, 3, 6)), to(_rand(2, 3, 5, seed=1))
    total = m.learn(pre=x, post=m(x), target=y)  # two rules: the summed change, checked finite
    return {"delta": total, "weight": m.weight}


def run_qlearning(m, to):
    x0, x1 = to(_rand(1, 4, 6)), to(_rand(1, 4, 6, seed=1))
    action = to(torch.tensor([[0, 2, 1, 2]]))
    reward = to(torch.tensor([[1.0, 0.0, 0.5, 1.0]]))
    done = to(torch.tensor([[False, True, False, False]]))
    m.learn(pre=x0, action=action, reward=reward, next_pre=x1, done=done)
    return {"weight": m.weight, "q": m(x1)}


def run_fixed(m, to):
    return {"forward": m(to(_rand(2, 4, 5))), "forward_2d": m(to(_rand(4, 5, seed=1)))}


def run_gain_field(m, to):
    return {"forward": m(to(_rand(3, 4)), to(_rand(3, 5, seed=1)))}


def run_som(m, to):
    X = to(_rand(6, 12))
    Xp = X.expand(2, -1, -1)  # (P, N, in)
    out = {"forward": m(Xp), "bmu": m.bmu(Xp)}
    out["winners_step"] = m.step(to(_rand(2, 12, seed=1)))
    order = to(seeding.randint(participant_generators(5, 2), 6, (20,)))
    out["winners_online"] = m.fit(X, iterations=20, order=order, method="online")
    out["winners_auto"] = m.fit(X, iterations=20, order=order)  # N = 6 < n_in = 12: factored (online on meta)
    out["weight"], out["steps"] = m.weight, m.steps
    out["qe"] = m.quantization_error(X)
    return out


def run_som_distance(m, to):
    return {"forward": m(to(_rand(2, 4, 12)))}


def run_supervised_som(m, to):
    X = to(_rand(5, 4))
    labels = to(torch.tensor([0, 1, 2, 3, 4]))
    m.step(X[:1], winner=labels[:1])
    order = to(seeding.randint(participant_generators(1, 1), 5, (15,)))
    out = {"winners": m.fit(X, iterations=15, labels=labels, order=order, method="online")}
    out["weight"], out["forward"] = m.weight, m(X)
    return out


def run_bidirectional(m, to):
    a, b = to(_rand(4, 6)), to(_rand(4, 3, seed=1))
    order = to(seeding.randint(participant_generators(2, 1), 4, (12,)))
    m.fit(a, b, labels=to(torch.tensor([0, 1, 2, 3])), iterations=12, order=order, method="online")
    return {"weight": m.weight, "forward": m(a), "backward": m.backward(b)}


def run_field(m, to):
    s = torch.zeros(3, 9)
    s[0, 2], s[1, 6], s[2, 4] = 0.8, 0.9, 0.7
    d = m(to(s + 0.01 * _rand(3, 9)), max_cycles=200)
    return {"winner": d.winner, "cycles": d.cycles, "decided": d.decided, "state": d.state}


def run_accumulator(m, to):
    inputs = to(torch.tensor([[0.6, 0.2], [0.3, 0.5], [0.1, 0.1]]))
    d = m(inputs, cycles=80, generator=_gen(3))  # noise from a CPU generator, wherever the inputs are
    d2 = m(inputs, cycles=10, state=d.state, active=~d.decided, generator=_gen(4))
    return {"winner": d.winner, "cycles": d.cycles, "decided": d.decided, "state": d.state, "state2": d2.state}


def run_map(m, to):
    code = m.encode(to(torch.tensor([0.2, 0.55, 0.9])))
    return {"code": code, "decoded": m.decode(code), "set": m.set(code.unsqueeze(0))}


def run_dmp(m, to):
    theta = to(0.5 * _rand(3, 35) - 0.25)
    return {"rollout": m.rollout(theta, to(torch.full((7,), 0.3)), duration_s=0.5, dt=0.01)}


CASES = {
    "AllToAll+Hebbian": (lambda: AllToAll(6, 5, participants=2, rules=Hebbian(0.1), seed=1), run_hebbian),
    "AllToAll+Hebbian+Delta": (lambda: AllToAll(6, 5, participants=2, rules=[Hebbian(0.1), Delta(0.2)],
                                                transfer_fn="sigmoid"), run_two_rules),
    "AllToAll+QLearning": (lambda: AllToAll(6, 3, rules=QLearning(eta=0.5), transfer_fn="threshold"), run_qlearning),
    "OneToOne": (lambda: OneToOne(5, value=0.5, transfer_fn="tanh"), run_fixed),
    "HardWired": (lambda: HardWired.permutation(torch.tensor([4, 3, 2, 1, 0])), run_fixed),
    "GainField": (lambda: GainField(4, 5), run_gain_field),
    "SOM": (lambda: SOM((3, 4), 12, participants=2, seed=2, iterations=30), run_som),
    "SOM-distance": (lambda: SOM((3, 4), 12, participants=2, readout="distance"), run_som_distance),
    "SOM-supervised": (lambda: SOM((5,), 4, supervised=True, sigma=1.0, iterations=20), run_supervised_som),
    "BidirectionalSOM": (lambda: BidirectionalSOM(4, 6, 3, iterations=12), run_bidirectional),
    "DynamicField": (lambda: DynamicField((9,), tau=5.0), run_field),
    "LeakyCompetingAccumulator": (lambda: LeakyCompetingAccumulator(2, noise=0.3), run_accumulator),
    "PopulationMap": (lambda: PopulationMap("m", (11,), sigma=0.1), run_map),
    "DMP": (lambda: DMP(), run_dmp),
}


def _converter(device, dtype):
    def to(t):
        return t.to(device=device, dtype=dtype) if t.is_floating_point() else t.to(device=device)
    return to


def _reference(name):
    make, run = CASES[name]
    return run(make(), lambda t: t)


def check_on(name, device, dtype):
    """Run block ``name`` moved to ``device``/``dtype`` with inputs there; compare with the reference."""
    make, run = CASES[name]
    ref = _reference(name)
    out = run(make().to(device=device, dtype=dtype), _converter(device, dtype))
    assert out.keys() == ref.keys()
    for key, r in ref.items():
        o = out[key]
        assert o.shape == r.shape, key
        assert o.device.type == torch.device(device).type, key
        assert o.dtype == (dtype if r.is_floating_point() else r.dtype), key
        if o.device.type == "meta":
            continue
        if r.is_floating_point():
            assert_close(o.cpu().to(r.dtype), r, **FLOAT32_REF, msg=f"{name}: {key}")
        else:
            assert torch.equal(o.cpu(), r), f"{name}: {key}"


@pytest.mark.parametrize("name", list(CASES))
def test_block_on_meta(name):
    check_on(name, "meta", torch.float32)


@pytest.mark.parametrize("name", list(CASES))
def test_block_in_float64(name):
    check_on(name, "cpu", torch.float64)


@CUDA
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("name", list(CASES))
def test_block_on_cuda(name, dtype):
    check_on(name, "cuda", dtype)


def test_learning_changes_the_weights():
    """The runs above learn something (else comparing weights with the reference would prove little)."""
    for name in ("AllToAll+Hebbian", "AllToAll+Hebbian+Delta", "AllToAll+QLearning", "SOM", "SOM-supervised",
                 "BidirectionalSOM"):
        make, _ = CASES[name]
        assert not torch.equal(_reference(name)["weight"], make().weight), name


@pytest.mark.parametrize("name", list(CASES))
def test_block_pickles(name):
    make, run = CASES[name]
    m = make()
    twins = pickle.loads(pickle.dumps(m)), copy.deepcopy(m)
    ours = run(m, lambda t: t)
    for twin in twins:
        theirs = run(twin, lambda t: t)
        for key in ours:
            assert torch.equal(ours[key], theirs[key]), f"{name}: {key}"


# ---------------------------------------------------------------------- SOM order from its own seed
def test_som_fit_draws_its_order_from_its_seed():
    X = _rand(8, 5)
    som = SOM((3, 3), 5, participants=2, seed=4, iterations=25).eval()  # eval(): fit returns the order only
    first, second = som.fit(X), som.fit(X)
    gens = participant_generators(4, 2, ORDER_STREAM)
    assert torch.equal(first, seeding.randint(gens, 8, (25,)))
    assert torch.equal(second, seeding.randint(gens, 8, (25,)))  # the next call carries the stream on
    assert not torch.equal(first, second)
    twin = SOM((3, 3), 5, participants=2, seed=4, iterations=25)
    trained = twin.fit(X)
    again = SOM((3, 3), 5, participants=2, seed=4, iterations=25)
    assert torch.equal(again.fit(X, generators=participant_generators(4, 2, ORDER_STREAM)), trained)
    assert torch.equal(again.weight, twin.weight)


def test_som_order_stream_survives_pickle():
    X = _rand(8, 5)
    som = SOM((3, 3), 5, seed=1, iterations=10)
    som.fit(X)
    copies = pickle.loads(pickle.dumps(som)), copy.deepcopy(som)
    winners = som.fit(X)
    for c in copies:
        assert torch.equal(c.fit(X), winners)
        assert torch.equal(c.weight, som.weight)


def test_som_built_from_generators_still_needs_an_order():
    som = SOM((3, 3), 5, generators=participant_generators(0, 1))
    with pytest.raises(ValueError, match="built from explicit generators"):
        som.fit(_rand(8, 5))


def test_windowed_fit_refuses_other_devices():
    som = SOM((3, 3), 5).to("meta")
    with pytest.raises(ValueError, match="meta device"):
        som.fit(_rand(8, 5).to("meta"), iterations=4, order=torch.zeros(1, 4, dtype=torch.long),
                method="windowed")


# ---------------------------------------------------------------------- value checks
def test_value_checks_can_be_switched_off():
    m = AllToAll(3, 2)
    bad = torch.tensor([[1.0, float("nan"), 0.0]])
    with pytest.raises(ValueError, match="NaN"):
        m(bad)
    with functional.checks(False):
        assert not functional.checks_enabled()
        assert torch.isnan(m(bad)).all()
    assert functional.CHECKS and functional.checks_enabled()
    assert not functional.checks_enabled(bad.to("meta"))
    with pytest.raises(ValueError, match="NaN"):
        DMP().rollout(torch.full((1, 35), float("nan")), torch.zeros(7))


@CUDA
def test_cuda_forward_and_learn_do_not_synchronise_without_checks():
    m = AllToAll(6, 5, participants=2, rules=Hebbian(0.1)).cuda()
    x, y = torch.rand(2, 3, 6, device="cuda"), torch.rand(2, 3, 5, device="cuda")
    torch.cuda.synchronize()
    torch.cuda.set_sync_debug_mode("error")
    try:
        with functional.checks(False):
            m.learn(pre=x, post=m(x))
        with pytest.raises(RuntimeError, match="synchroniz"):
            m(x)  # the finiteness check reads a value on the host
    finally:
        torch.cuda.set_sync_debug_mode("default")


# ---------------------------------------------------------------------- torch.compile
def _alltoall_pair():
    make = lambda: AllToAll(6, 5, participants=2, rules=Hebbian(0.1, form="instar"), seed=3)  # noqa: E731
    return make(), make(), _rand(2, 3, 6), _rand(2, 3, 5, seed=1)


def test_forward_and_hebbian_learn_have_no_graph_break():
    torch._dynamo.reset()
    m, _, x, y = _alltoall_pair()
    fwd = torch._dynamo.explain(m)(x)
    assert (fwd.graph_count, fwd.graph_break_count) == (1, 0), fwd.break_reasons

    def learn(pre, post):
        m.learn(pre=pre, post=post)
        return m.weight

    step = torch._dynamo.explain(learn)(x, y)
    assert (step.graph_count, step.graph_break_count) == (1, 0), step.break_reasons

    delta = AllToAll(6, 5, participants=2, rules=Delta(0.2))

    def learn_delta(pre, post, target):
        delta.learn(pre=pre, post=post, target=target)
        return delta.weight

    step = torch._dynamo.explain(learn_delta)(x, y, y.flip(-1))
    assert (step.graph_count, step.graph_break_count) == (1, 0), step.break_reasons


def test_compiled_forward_and_hebbian_learn_equal_eager():
    torch._dynamo.reset()
    eager, compiled, x, y = _alltoall_pair()
    fwd = torch.compile(compiled, fullgraph=True, backend="eager")
    assert_close(fwd(x), eager(x))

    @torch.compile(fullgraph=True, backend="eager")
    def learn(pre, post):
        compiled.learn(pre=pre, post=post)
        return compiled.weight

    for _ in range(2):
        learn(x, y)
        eager.learn(pre=x, post=y)
    assert_close(compiled.weight, eager.weight)
    assert not torch.equal(eager.weight, _alltoall_pair()[0].weight)
    assert_close(fwd(x), eager(x))


def test_field_computes_in_the_dtype_of_its_input():
    field = DynamicField((9,), tau=5.0)  # float32 kernel
    s = 0.8 * torch.eye(9)[:3].double()
    d = field(s, max_cycles=200)
    d64 = DynamicField((9,), tau=5.0).double()(s, max_cycles=200)
    assert d.state.dtype == torch.float64
    assert torch.equal(d.state, d64.state)  # the kernel cast to float64 is the float64 module's kernel
    assert torch.equal(d.cycles, d64.cycles)


# ---------------------------------------------------------------------- arm kinematics
# FK composes about ten 4x4 transforms of O(1) entries (rotations, positions within 1.4 m); each
# product rounds once in float32, so float32 and float64 poses differ by a few eps (2.2 eps
# measured on these 64 postures): 16 eps leaves a factor 7 of margin
ARM_TOL = dict(rtol=0.0, atol=16 * torch.finfo(torch.float32).eps)


@pytest.fixture(scope="module")
def arm():
    from neuroimagery.robot.kinematics import ArmKinematics

    return ArmKinematics


def _postures(kin, n=64):
    lo, hi = kin.joint_limits[:, 0], kin.joint_limits[:, 1]
    return lo + (hi - lo) * _rand(n, 7)


def test_arm_kinematics_in_float64(arm):
    k32, k64 = arm(), arm().double()
    assert k64.arm.dtype == k64.head.dtype == k64.arm._static_offsets.dtype == torch.float64
    q = _postures(k32)
    for f in ("forward", "rake_pose", "rake_head_position"):
        ours = getattr(k64, f)(q.double())
        assert ours.dtype == torch.float64, f
        assert_close(ours, getattr(k32, f)(q).double(), **ARM_TOL, msg=f)
    assert_close(k64.eye_pose(), k32.eye_pose().double(), **ARM_TOL)
    assert torch.equal(k64.float()(q), k32(q))  # float32 -> float64 -> float32 is exact


def test_arm_kinematics_on_meta(arm):
    k = arm()
    q = _postures(k).reshape(4, 16, 7)
    km = arm().to("meta")
    assert torch.device(km.arm.device).type == km.arm._static_offsets.device.type == "meta"
    km.check_limits(q.to("meta"))  # no values to check: nothing raised
    for f in ("forward", "rake_pose"):
        out = getattr(km, f)(q.to("meta"))
        assert out.device.type == "meta" and out.shape == (4, 16, 4, 4), f
    assert km.rake_head_position(q.to("meta")).shape == (4, 16, 3)
    assert km.eye_pose().shape == (4, 4) and km.eye_pose().device.type == "meta"


def test_arm_kinematics_pickles(arm):
    k = arm()
    q = _postures(k)
    assert torch.equal(pickle.loads(pickle.dumps(k)).rake_pose(q), k.rake_pose(q))


@CUDA
def test_arm_kinematics_on_cuda(arm):
    k = arm()
    q = _postures(k)
    kc = arm().cuda()
    assert_close(kc.rake_pose(q.cuda()).cpu(), k.rake_pose(q), **ARM_TOL)
    assert_close(kc.double().rake_pose(q.cuda().double()).cpu(), k.rake_pose(q).double(), **ARM_TOL)
