"""Portable numerics: the rounding bound, and Exp. 3-4 training at one and at two threads."""
import pytest
import torch
from conftest import make_cfg

from neuroimagery.config import validate
from neuroimagery.experiments.exp3 import protocol as exp3
from neuroimagery.experiments.exp4 import protocol as exp4
from neuroimagery.experiments.chapter6 import protocol as pc
from neuroimagery.nn import AllToAll, Delta, seeding
from neuroimagery.nn.numerics import rounding_bound, rounding_bound_nonneg


@pytest.fixture
def threads():
    """``threads(n)`` sets the intra-op thread count for the test; the suite's count is restored after."""
    before = torch.get_num_threads()
    yield torch.set_num_threads
    torch.set_num_threads(before)


def test_rounding_bound_covers_reordered_sums():
    """One float32 sum of 4096 products in five orders (sequential, in two halves and reversed,
    torch.sum, a matrix-vector product, float64 rounded once): all within the bound of each
    other."""
    g = torch.Generator().manual_seed(0)
    a, b = torch.rand(4096, generator=g) - 0.5, torch.rand(4096, generator=g)
    t = a * b

    def seq(v):
        s = torch.zeros(())
        for x in v:
            s = s + x
        return s

    sums = [seq(t[:512]) + seq(t[512:]), seq(t.flip(0)), t.sum(), a @ b, (a.double() @ b.double()).float()]
    bound = rounding_bound((a.double().abs() @ b.double()).item(), 4096)
    assert max(float(s) for s in sums) - min(float(s) for s in sums) <= bound
    with pytest.raises(ValueError, match="too many"):
        rounding_bound(1.0, 2**24)


def _delta_weights(X: torch.Tensor, Y: torch.Tensor) -> torch.Tensor:
    c = AllToAll(X.shape[-1], 1024, participants=X.shape[0], seed=0, rules=Delta(0.02))
    c.learn(X, None, sequence=True, batch=8, target=Y, method="delta_binary")
    return c.weight.clone()


@pytest.mark.parametrize("P", [1, 3])  # odd: the participants do not split evenly between two threads
def test_delta_rule_training_is_the_same_at_one_and_two_threads(threads, P):
    """Exp. 3's forward-model training (eq. 6.4, 3 x 1024 -> 1024, mini-batches of 8) gives the
    same weights at one and at two threads, bit for bit and run after run: each weight is a fixed
    sequence of float32 additions and products (no BLAS, ``index_add_`` in index order), so no
    tolerance applies. (The former ``index_put_(accumulate=True)`` gave 0.1-1.6 % of the weights
    of such runs other last bits at two threads, differently from run to run.)"""
    gens = seeding.participant_generators(0, list(range(P)), stream=1)
    X, Y, _ = pc.three_dot_training_set(gens, 600, [30.0, 0.0, -30.0], 32, 23, offsets=(0, 1, 2))
    threads(1)
    one = _delta_weights(X, Y)
    threads(2)
    for _ in range(2):
        assert torch.equal(_delta_weights(X, Y), one)


def test_exp4_trained_at_two_threads_answers_as_at_one(threads):
    """A tiny Exp. 4 model (1 participant, 300 forward-model images) trained and tested at two
    threads gives the answers, RTs and rotation steps it gives at one. Forward models: the same
    weights bit for bit (see the test above). Posture maps (C16, C17, supervised, factored): the
    winners are the labels and the recurrences elementwise, so only their final float32 product
    ``c W0 + (c R)^T X`` over the N training maps may round otherwise (BLAS at other thread
    counts); every term is >= 0, so they agree within the bound of an (N + 1)-term sum."""
    cfg = validate(make_cfg("experiment=exp4", "participants=1", "logger=none", "experiment.quick.fm_images=300",
                            "experiment.posture.iterations=100"))
    cfg.preset = "quick"
    bank = pc.StimulusBank.build(pc.make_eye(cfg), pc.stimulus_set(cfg, "exp4-A", False), 32)
    table = pc.trial_table(bank, "recog", "noise-mismatch").iloc[:60]
    tgt = bank.maps[torch.as_tensor(table["target_row"].to_numpy().copy())].unsqueeze(0)
    rot = bank.maps[torch.as_tensor(table["rotated_row"].to_numpy().copy())].unsqueeze(0)
    n_maps = len(pc.stimulus_set(cfg, cfg.experiment.train_set, use_user_folder=False).items())
    res = {}
    for n in (1, 2):
        threads(n)
        model = exp4.train_model(cfg, [0])
        out = model.run(tgt, rot, seeding.participant_generators(0, [0], 100), proprioception="mismatch", noise=True)
        res[n] = model, out
    (m1, o1), (m2, o2) = res[1], res[2]
    for a, b in zip(m1.fm, m2.fm):
        assert torch.equal(a.weight, b.weight)
    for a, b in ((m1.c16, m2.c16), (m1.c17, m2.c17)):
        assert ((a.weight - b.weight).abs() <= rounding_bound_nonneg(a.weight, n_maps + 1)).all()
    for k in ("answer", "rt", "rotation_steps"):
        assert torch.equal(o1[k], o2[k]), k


def test_exp3_forward_model_is_the_same_at_two_threads(threads):
    """Exp. 3's forward model C6 trained by ``train_model`` (1 participant, 300 images): the same
    weights at two threads as at one, bit for bit (the delta rule above, inside the experiment)."""
    cfg = validate(make_cfg("experiment=exp3", "participants=1", "logger=none", "experiment.quick.fm_images=300",
                            "experiment.posture.iterations=10"))
    cfg.preset = "quick"
    w = {}
    for n in (1, 2):
        threads(n)
        w[n] = exp3.train_model(cfg, [0]).c6.weight.clone()
    assert torch.equal(w[1], w[2])


def test_large_uniform_draws_side_by_side_equal_one_at_a_time(monkeypatch):
    """seeding.uniform draws big per-participant tensors on several threads: every participant's
    numbers are those of its own generator drawn alone, at any thread count."""
    from neuroimagery.nn import seeding

    shape = (300, 40)
    solo = [seeding.uniform(seeding.participant_generators(3, [p]), shape, -0.5, 0.5)[0] for p in range(5)]
    monkeypatch.setattr(seeding, "PARALLEL_DRAW", 1)  # every draw takes the threaded path
    for threads in (1, 2, 3):
        prev = torch.get_num_threads()
        torch.set_num_threads(threads)
        try:
            batch = seeding.uniform(seeding.participant_generators(3, 5), shape, -0.5, 0.5)
        finally:
            torch.set_num_threads(prev)
        for p in range(5):
            assert torch.equal(batch[p], solo[p]), (threads, p)


def test_thread_budget_is_the_outermost_setting():
    from neuroimagery.nn.functional import intra_op_threads, thread_budget

    with intra_op_threads(2):
        with intra_op_threads(1, cap=True):
            assert torch.get_num_threads() == 1 and thread_budget() == 2
    with intra_op_threads(1):
        assert thread_budget() == 1
    assert thread_budget() == torch.get_num_threads()
