"""DMP (eq. 7.2-7.5): analytic spring solution, per-rollout loop, independent scalar integration."""
import math

import numpy as np
import pytest
import torch

from neuroimagery.motor.dmp import DMP


def test_parameter_layout():
    dmp = DMP(max_goal_offset=None)
    assert dmp.n_params == 35
    g = torch.arange(7.0).unsqueeze(0)
    w = torch.arange(28.0).reshape(1, 7, 4) + 100
    theta = dmp.pack(g, w)
    assert theta[0, :7].tolist() == g[0].tolist()
    assert theta[0, 7:11].tolist() == [100, 101, 102, 103]  # joint 0's four weights come first
    g2, w2 = dmp.split(theta)
    assert torch.equal(g2, g) and torch.equal(w2, w)


@pytest.mark.parametrize("beta", [6.25, 3.0, 20.0])  # critical, over- and under-damped
def test_zero_forcing_matches_analytical_solution(beta):
    dmp = DMP(alpha_v=25.0, beta_v=beta, max_goal_offset=None)
    gen = torch.Generator().manual_seed(0)
    y0 = torch.randn(5, 7, generator=gen, dtype=torch.float64)
    g = torch.randn(5, 7, generator=gen, dtype=torch.float64)
    theta = dmp.pack(g, torch.zeros(5, 7, 4, dtype=torch.float64))
    num = dmp.rollout(theta, y0, duration_s=1.0, dt=1e-4)
    ana = dmp.analytical_solution(g, y0, duration_s=1.0, dt=1e-4)
    assert num.shape == ana.shape == (5, 10001, 7)
    assert (num - ana).abs().max() < 2e-3 * (g - y0).abs().max()
    if beta == 6.25:  # critically damped: converged near the goal after tau
        assert (num[:, -1] - g).abs().max() < 0.05


def test_zero_forcing_when_goal_equals_start():
    dmp = DMP(max_goal_offset=None)
    y0 = torch.rand(2, 7)
    theta = dmp.pack(y0.clone(), 500 * torch.randn(2, 7, 4))  # forcing scales with (g - y0) = 0
    out = dmp.rollout(theta, y0, 1.0, 0.01)
    assert torch.allclose(out, y0.unsqueeze(1).expand_as(out), atol=1e-6)


def _scalar_dmp(dmp, g, w, y0, tau, dt):
    """Independent per-joint scalar integration written straight from eq. 7.2-7.5."""
    c, h = dmp.centres.double().numpy(), dmp.widths.double().numpy()
    y, v, x, out = y0, 0.0, 1.0, [y0]
    for s in range(int(round(tau / dt))):
        x = math.exp(-dmp.alpha_x * s * dt / tau)
        psi = np.exp(-h * (x - c) ** 2)
        f = (psi @ w) / psi.sum() * x * (g - y0)
        acc = (dmp.alpha_v * (dmp.beta_v * (g - y) - tau * v) + f) / tau**2
        v += dt * acc
        y += dt * v
        out.append(y)
    return np.array(out)


def test_batched_equals_per_rollout_loop_and_scalar_reference():
    dmp = DMP(max_goal_offset=None)
    gen = torch.Generator().manual_seed(2)
    theta = torch.cat([torch.randn(6, 7, generator=gen), 200 * torch.randn(6, 28, generator=gen)], 1).double()
    y0 = torch.randn(6, 7, generator=gen).double()
    batched = dmp.rollout(theta, y0, 1.5, 0.01)
    loop = torch.cat([dmp.rollout(theta[i : i + 1], y0[i], 1.5, 0.01) for i in range(6)])
    assert torch.allclose(batched, loop, atol=1e-12)
    g, w = dmp.split(theta)
    for i in (0, 3):
        for j in (0, 4):
            ref = _scalar_dmp(dmp, float(g[i, j]), w[i, j].numpy(), float(y0[i, j]), 1.5, 0.01)
            assert np.allclose(batched[i, :, j].numpy(), ref, atol=1e-9)
    # the forcing term really shapes the movement
    flat = dmp.rollout(dmp.pack(g, torch.zeros_like(w)), y0, 1.5, 0.01)
    assert (flat - batched).abs().max() > 0.05


def test_bad_parameters_raise():
    dmp = DMP()
    theta = torch.zeros(2, 35)
    theta[1, 9] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        dmp.rollout(theta, torch.zeros(7))
    with pytest.raises(ValueError, match=r"\(N, 35\)"):
        dmp.rollout(torch.zeros(2, 34), torch.zeros(7))
    with pytest.raises(ValueError, match="dt"):
        dmp.rollout(torch.zeros(1, 35), torch.zeros(7), duration_s=1.0, dt=0.0)


def test_goal_offset_bound_limits_the_movement_to_the_start_neighbourhood():
    from neuroimagery.motor.dmp import MAX_GOAL_OFFSET_RAD

    bounded, free = DMP(), DMP(max_goal_offset=None)
    assert bounded.max_goal_offset == MAX_GOAL_OFFSET_RAD
    y0 = torch.tensor([0.1, -0.2, 0.0, 0.5, 0.0, 0.3, -0.1], dtype=torch.float64)
    far = y0 + torch.tensor([1.0, -1.0, 0.05, 0.4, -0.3, 0.0, 0.2], dtype=torch.float64)
    theta = bounded.pack(far[None], torch.zeros(1, 7, 4, dtype=torch.float64))
    end = bounded.rollout(theta, y0, 1.5, 0.01)[0, -1]
    expected = y0 + (far - y0).clamp(-MAX_GOAL_OFFSET_RAD, MAX_GOAL_OFFSET_RAD)
    assert torch.allclose(end, expected, atol=5e-3)  # converges to the bounded goal
    # the same parameters with the goal already inside the bound: identical to the unbounded DMP
    near = bounded.pack(expected[None], 50 * torch.randn(1, 7, 4, dtype=torch.float64))
    assert torch.allclose(bounded.rollout(near, y0, 1.5, 0.01), free.rollout(near, y0, 1.5, 0.01))
    with pytest.raises(ValueError, match="max_goal_offset"):
        DMP(max_goal_offset=0.0)


def test_compiled_rollout_gives_the_torch_loops_bits():
    """motor.dmp_kernel integrates float32 rollouts with the torch loop's operations in its order:
    identical trajectories (both start postures' layouts, several step sizes)."""
    from neuroimagery.motor import dmp_kernel

    if not dmp_kernel.available(torch.zeros(1)):
        pytest.skip("numba is not installed")
    g = torch.Generator().manual_seed(5)
    d = DMP()
    for trial in range(30):
        n = trial % 7 + 1
        theta = torch.randn(n, 35, generator=g) * torch.tensor([1.0] * 7 + [300.0] * 28)
        y0 = torch.randn(n, 7, generator=g) * 0.5 if trial % 2 else torch.randn(7, generator=g) * 0.5
        duration, dt = [(1.5, 0.02), (2.0, 0.01), (1.0, 0.005)][trial % 3]
        d.compiled = False
        plain = d.rollout(theta, y0, duration, dt)
        d.compiled = True
        assert torch.equal(d.rollout(theta, y0, duration, dt), plain), trial


def test_rollout_keeps_gradients_through_the_parameters():
    """A rollout whose parameters need a gradient takes the torch loop, so the trajectory is
    differentiable in the goals and weights (a model that learns through a DMP)."""
    d = DMP()
    theta = (torch.randn(3, 35, generator=torch.Generator().manual_seed(2)) * 0.3).requires_grad_()
    traj = d.rollout(theta, torch.zeros(7), 1.0, 0.02)
    traj[:, -1].sum().backward()
    assert theta.grad is not None and theta.grad[:, :7].abs().sum() > 0  # the end posture follows the goals
