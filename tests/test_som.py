"""SOMs: topology on 1-D input, exactness of the factored fit, supervised fitting, bidirectional SOM."""
import pytest
import torch

from neuroimagery.nn import SOM, BidirectionalSOM, participant_generators
from neuroimagery.nn import seeding
from neuroimagery.nn import som as som_module


def test_som_on_1d_input_keeps_topology():
    # inputs on a line: after training, prototypes along the 1-D map are monotonic
    X = torch.linspace(0, 1, 50).unsqueeze(1)
    som = SOM((10,), 1, participants=3, seed=2, eta=0.5, sigma=3.0, eta_final=0.01, sigma_final=0.5, iterations=2000)
    som.fit(X, generators=participant_generators(2, 3), method="online")
    for p in range(3):
        w = som.weight[p, :, 0]
        diffs = w[1:] - w[:-1]
        assert bool((diffs > 0).all()) or bool((diffs < 0).all()), w
    assert float(som.topographic_error(X).max()) == 0.0


@pytest.mark.parametrize("supervised", [False, True])
def test_factored_fit_equals_online_rule(supervised):
    X = (torch.rand(30, 400, generator=torch.Generator().manual_seed(0)) > 0.7).float()
    labels = torch.arange(30) % 6 if supervised else None
    shape = (6,) if supervised else (8, 8)
    kw = dict(participants=2, seed=4, eta=0.3, sigma=2.0, eta_final=0.02, sigma_final=0.5, iterations=800, supervised=supervised)
    a, b = SOM(shape, 400, **kw), SOM(shape, 400, **kw)
    order = seeding.randint(participant_generators(9, 2), 30, (800,))
    wa = a.fit(X, labels=labels, order=order, method="online")
    wb = b.fit(X, labels=labels, order=order, method="factored")
    if supervised:  # the winners are forced to the labels, so comparing them tests nothing else
        assert torch.equal(wa, labels[order]) and torch.equal(wb, labels[order])
    else:
        assert torch.equal(wa, wb)  # same winners at every step
    assert torch.allclose(a.weight, b.weight, atol=1e-5)
    assert torch.allclose(a.quantization_error(X), b.quantization_error(X), atol=1e-5)


def test_supervised_readout_picks_labelled_unit():
    X = torch.eye(4).repeat_interleave(1, 0) * 1.0
    som = SOM((4,), 4, participants=1, supervised=True, eta=0.5, sigma=0.3, iterations=200)
    som.fit(X, labels=torch.tensor([2, 0, 3, 1]), generators=participant_generators(0, 1))
    y = som(X)  # (4, 4) max-normalised
    assert y.argmax(-1).tolist() == [2, 0, 3, 1]
    assert torch.allclose(y.max(-1).values, torch.ones(4))
    assert torch.allclose(som.weight.sum(-1), torch.ones(1, 4), atol=1e-5)


def test_batched_participants_equal_solo_runs():
    X = torch.rand(20, 16, generator=torch.Generator().manual_seed(1))
    batch = SOM((5, 5), 16, generators=participant_generators(3, 3), iterations=300)
    batch.fit(X, generators=participant_generators(3, 3, stream=1))
    for p in range(3):
        solo = SOM((5, 5), 16, generators=participant_generators(3, [p]), iterations=300)
        solo.fit(X, generators=participant_generators(3, [p], stream=1))
        assert torch.allclose(solo.weight[0], batch.weight[p], atol=1e-6)


def test_bidirectional_som_runs_both_ways():
    a = torch.eye(5)  # five "images"
    b = torch.eye(5).flip(0)  # paired "actions"
    bs = BidirectionalSOM(5, 5, 5, eta=0.5, sigma=0.3, iterations=300)
    bs.fit(a, b, labels=torch.arange(5), generators=participant_generators(0, 1))
    assert bs(a.unsqueeze(0))[0].argmax(-1).tolist() == [4, 3, 2, 1, 0]
    assert bs.backward(b.unsqueeze(0))[0].argmax(-1).tolist() == [0, 1, 2, 3, 4]


def test_som_bad_inputs():
    som = SOM((3, 3), 4)
    with pytest.raises(ValueError, match="patterns"):
        som.fit(torch.rand(5, 3), generators=participant_generators(0, 1))
    with pytest.raises(ValueError, match="NaN"):
        som(torch.full((2, 4), float("nan")))
    with pytest.raises(ValueError, match="method"):
        som.fit(torch.rand(5, 4), generators=participant_generators(0, 1), method="magic")
    with pytest.raises(ValueError, match="supervised"):
        SOM((3,), 4, supervised=True).fit(torch.rand(5, 4), generators=participant_generators(0, 1))


def test_windowed_fit_equals_online_rule():
    X = (torch.rand(25, 300, generator=torch.Generator().manual_seed(3)) > 0.7).float()
    kw = dict(participants=3, seed=5, eta=0.3, sigma=3.0, eta_final=0.02, sigma_final=0.5, iterations=400)
    a, b = SOM((9, 9), 300, **kw), SOM((9, 9), 300, **kw)
    order = seeding.randint(participant_generators(2, 3), 25, (400,))
    wa = a.fit(X, order=order, method="online")
    wb = b.fit(X, order=order, method="windowed")
    assert torch.equal(wa, wb)
    assert torch.allclose(a.weight, b.weight, atol=1e-5)


def test_windowed_fit_by_pieces_and_jointly_equals_online_rule():
    """Patterns made of pieces ([a_i, b_j]: 4 x 3 pieces, 12 patterns): the windowed fit over the
    distinct pieces (``parts``), and two maps trained together (``fit_windowed_many``), give the
    online rule's winners; the joint fit gives each map the weights of its own fit, to within the
    rounding of the final products (the joint loop works on other shapes)."""
    from neuroimagery.nn.numerics import rounding_bound
    from neuroimagery.nn.som_windowed import fit_windowed, fit_windowed_many

    g = torch.Generator().manual_seed(7)
    A, B = (torch.rand(4, 120, generator=g) > 0.6).float(), (torch.rand(3, 80, generator=g) > 0.6).float()
    X = torch.cat([A.repeat_interleave(3, 0), B.repeat(4, 1)], 1)  # (12, 200)
    Y = (torch.rand(9, 150, generator=g) > 0.5).float()
    kw = dict(participants=2, eta=0.3, sigma=3.0, eta_final=0.02, sigma_final=0.5, iterations=300)
    mk = lambda n_in, seed: SOM((9, 9), n_in, seed=seed, **kw)  # noqa: E731
    ox = seeding.randint(participant_generators(1, 2), 12, (300,))
    oy = seeding.randint(participant_generators(2, 2), 9, (300,))
    ref_x, ref_y = mk(200, 3), mk(150, 4)
    wx, wy = ref_x.fit(X, order=ox, method="online"), ref_y.fit(Y, order=oy, method="online")
    solo = mk(200, 3)
    assert torch.equal(fit_windowed(solo, X, ox, parts=(120, 80)), wx)
    assert torch.allclose(solo.weight, ref_x.weight, atol=1e-5)
    jx, jy = mk(200, 3), mk(150, 4)
    vx, vy = fit_windowed_many([(jx, X, ox, (120, 80)), (jy, Y, oy, None)])
    assert torch.equal(vx, wx) and torch.equal(vy, wy)
    # the weights are scale * w0 + coef @ X, with scale and coef from float64 recurrences that are
    # element for element the same: if they round differently their float32 values move by at most
    # one ulp (one more term's worth of rounding), and the float32 product of N patterns adds N + 1
    f = solo.learnt_factors
    mag = f["scale"].abs().unsqueeze(-1) * mk(200, 3).weight.abs() + f["coef"].abs() @ f["patterns"].abs()
    assert ((jx.weight - solo.weight).abs() <= rounding_bound(mag, f["coef"].shape[-1] + 2)).all()
    assert torch.allclose(jy.weight, ref_y.weight, atol=1e-5)
    with pytest.raises(ValueError, match="parts"):
        fit_windowed(mk(200, 3), X, ox, parts=(100, 80))


def test_windowed_compiled_loop_gives_the_torch_loops_bits(monkeypatch):
    """The compiled step loop of the windowed fit (numba) does the torch loop's float64 arithmetic
    in the same order: winners, weights and factors are the same bits, for two maps trained
    together (pieces, a padded piece column) and with scales small enough to be folded back."""
    from neuroimagery.nn import som_windowed_kernel as kernel
    from neuroimagery.nn.som_windowed import fit_windowed_many

    if not kernel.available():
        pytest.skip("numba is not installed: the torch loop is the only one")
    g = torch.Generator().manual_seed(11)
    A, B = torch.rand(4, 60, generator=g) ** 8, (torch.rand(3, 40, generator=g) > 0.6).float()
    X = torch.cat([A.repeat_interleave(3, 0), B.repeat(4, 1)], 1)  # (12, 100): 4 x 3 pieces
    Y = (torch.rand(9, 70, generator=g) > 0.5).float()
    kw = dict(participants=3, eta=0.6, sigma=4.0, eta_final=0.3, sigma_final=0.8, iterations=400)
    ox = seeding.randint(participant_generators(1, 3), 12, (400,))
    oy = seeding.randint(participant_generators(2, 3), 9, (400,))
    runs = []
    from neuroimagery.nn import compiled as numba_loops

    for compiled in (True, False):
        if not compiled:
            monkeypatch.setattr(numba_loops, "numba", None)
        maps = SOM((6, 7), 100, seed=3, **kw), SOM((6, 7), 70, seed=4, **kw)
        for m in maps:
            m.rule.cutoff = 0.01
        win = fit_windowed_many([(maps[0], X, ox, (60, 40)), (maps[1], Y, oy, None)])
        runs.append((win, [m.weight.clone() for m in maps], [m.learnt_factors for m in maps]))
    (wa, Wa, Fa), (wb, Wb, Fb) = runs
    assert all(torch.equal(x, y) for x, y in zip(wa, wb))
    assert all(torch.equal(x, y) for x, y in zip(Wa, Wb))
    assert all(fa.keys() == fb.keys() and all(torch.equal(fa[k], fb[k]) for k in fa if k != "kind") for fa, fb in zip(Fa, Fb))
    assert (Fa[0]["scale"] < 1e-12).any()  # below the fold threshold: some scales were folded back


def test_fit_together_gives_each_map_its_own_fit():
    """``fit_together`` trains the windowed maps of one schedule in one loop: each map gets the
    winners, weights and step count of its own ``SOM.fit``; a map of another implementation trains
    alone, and one in eval mode returns its order, as ``fit`` does."""
    from neuroimagery.nn.som import fit_together

    g = torch.Generator().manual_seed(3)
    X, Y = (torch.rand(10, 50, generator=g) > 0.5).float(), torch.rand(7, 30, generator=g)
    kw = dict(participants=2, eta=0.3, sigma=3.0, eta_final=0.02, sigma_final=0.5, iterations=200)
    ox = seeding.randint(participant_generators(1, 2), 10, (200,))
    oy = seeding.randint(participant_generators(2, 2), 7, (200,))
    mk = lambda: (SOM((8, 8), 50, seed=1, **kw), SOM((8, 8), 30, seed=2, **kw), SOM((5,), 30, seed=3, **kw))  # noqa: E731
    fits = lambda m: [(m[0], dict(patterns=X, order=ox, method="windowed")),  # noqa: E731
                      (m[1], dict(patterns=Y, order=oy, method="windowed")), (m[2], dict(patterns=Y, order=oy, method="online"))]
    alone, joint = mk(), mk()
    ref = [som.fit(**f) for som, f in fits(alone)]
    got = fit_together(fits(joint))
    for a, b, wa, wb in zip(alone, joint, ref, got):
        assert torch.equal(wa, wb) and torch.equal(a.weight, b.weight) and int(a.steps) == int(b.steps) == 200
    evald = mk()[0].eval()
    assert torch.equal(fit_together([(evald, dict(patterns=X, order=ox, method="windowed"))])[0], ox)


def test_windowed_weights_rebuild_from_their_factors():
    """The windowed fit keeps what it formed the weights from (scale, coefficients, patterns);
    those and the initial weights give the trained weights again, bit for bit, at a fraction of
    their size. A map trained otherwise has no factors."""
    from neuroimagery.nn.som_windowed import fit_windowed, rebuild_windowed

    X = (torch.rand(12, 400, generator=torch.Generator().manual_seed(4)) > 0.7).float()
    kw = dict(participants=2, seed=6, eta=0.3, sigma=3.0, eta_final=0.02, sigma_final=0.5, iterations=200)
    a, fresh = SOM((9, 9), 400, **kw), SOM((9, 9), 400, **kw)
    fit_windowed(a, X, seeding.randint(participant_generators(2, 2), 12, (200,)))
    f = a.learnt_factors
    assert f["kind"] == "som_windowed"
    assert f["coef"].shape == (2, 81, 12) and f["patterns"].shape == (12, 400)
    rebuild_windowed(fresh, f)
    assert torch.equal(fresh.weight, a.weight)  # the trainer's own products, same shapes and threads
    with pytest.raises(ValueError, match="do not fit"):
        rebuild_windowed(SOM((9, 9), 400, participants=3), f)
    other = SOM((9, 9), 400, **kw)
    other.fit(X, iterations=20, method="windowed")
    assert other.learnt_factors["kind"] == "som_windowed"
    other.fit(X, iterations=20, method="online")  # a later fit by another form leaves none
    assert SOM((9, 9), 400).learnt_factors is None and other.learnt_factors is None


def _repeated_case(sigma=0.1, iterations=1, eta_final=None, seed=5):
    """A C3-like bidirectional map: one labelled pair presented 50 times."""
    kw = dict(seed=seed, eta=0.1, sigma=sigma, iterations=iterations, eta_final=eta_final)
    g = torch.Generator().manual_seed(seed)
    a, b = torch.rand(1, 1, 30, generator=g), torch.rand(1, 1, 12, generator=g)
    return BidirectionalSOM(8, 30, 12, **kw), BidirectionalSOM(8, 30, 12, **kw), a, b


def test_repeated_fit_equals_plain_rule():
    # the closed form w <- x + (1 - eta)^T (w - x) against T plain steps (SOM.step), twice in a row
    # (the second fit starts at step 50, where the schedule is the same constant rate)
    fast, plain, a, b = _repeated_case()
    for label, T in ((3, 50), (3, 7), (6, 50)):
        order, labels = torch.zeros(1, T, dtype=torch.long), torch.tensor([[label]])
        assert som_module.choose(fast.som, torch.cat([a, b], -1), labels, "auto", {}, order).name == "repeated"
        wf = fast.fit(a, b, labels=labels, iterations=T, order=order)
        plain.som.supervised = True
        wp = som_module.fit_plain(plain.som, torch.cat([a, b], -1), order, labels)
        assert torch.equal(wf, wp)  # identical winners: the label at every step
        assert torch.allclose(fast.weight, plain.weight, rtol=0, atol=1e-6)  # float32 rounding of 50 steps
        assert int(fast.som.steps) == int(plain.som.steps)


@pytest.mark.parametrize("case", ["wide", "decaying", "changing"])
def test_repeated_fit_only_where_it_holds(case):
    # a neighbourhood wider than the winner, a rate that still decays, or patterns that change:
    # auto falls back on another implementation and an explicit request is refused
    fast, _, a, b = _repeated_case(sigma=2.0 if case == "wide" else 0.1,
                                   iterations=100 if case == "decaying" else 1,
                                   eta_final=0.01 if case == "decaying" else None)
    X, T = torch.cat([a, b], -1), 10
    order, labels = torch.zeros(1, T, dtype=torch.long), torch.tensor([[3]])
    if case == "changing":
        X, labels = X.expand(1, 2, -1).clone(), torch.tensor([[3, 4]])
        order[0, 5:] = 1
    assert som_module.choose(fast.som, X, labels, "auto", {}, order).name != "repeated"
    with pytest.raises(ValueError, match="method='repeated' needs"):
        som_module.choose(fast.som, X, labels, "repeated", {}, order)
