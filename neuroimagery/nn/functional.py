"""Stateless helpers shared by the blocks: transfer functions, Gaussian bumps, gain fields,
softmax selection and input checks.

Checks that read a tensor's values (finiteness of an input, a label in range) make the host wait
for the device and have nothing to read on the ``meta`` device. They run only while
:func:`checks_enabled` says so: ``CHECKS`` is true (the default; :func:`checks` switches it for a
block of code), the code is not being traced by ``torch.compile``, and the tensor is not on
``meta``. Checks of shapes and of Python numbers always run."""
from __future__ import annotations

import contextlib
from typing import Callable, Sequence

import torch

from ..core.errors import UserInputError
from .limits import check_rate

CHECKS = True  # run the value checks that synchronise with the device (see checks_enabled)


def checks_enabled(x: torch.Tensor | None = None) -> bool:
    """Whether checks that read tensor values (and so wait for the device) run now: ``CHECKS`` is
    true, ``torch.compile`` is not tracing, and ``x`` (if given) is not on the ``meta`` device."""
    if not CHECKS or torch.compiler.is_compiling():
        return False
    return x is None or x.device.type != "meta"


@contextlib.contextmanager
def checks(enabled: bool):
    """Switch the value checks of every block on or off inside a ``with`` block (restored after)."""
    global CHECKS
    before, CHECKS = CHECKS, bool(enabled)
    try:
        yield
    finally:
        CHECKS = before


def identity(x: torch.Tensor) -> torch.Tensor:
    """``F(x) = x``."""
    return x


def threshold(x: torch.Tensor) -> torch.Tensor:
    """``F(x) = 1`` where ``x > 0``, else 0, in ``x``'s dtype."""
    return (x > 0).to(x.dtype)


# module-level callables (not lambdas), so a block holding one can be pickled
TRANSFER: dict[str, Callable[[torch.Tensor], torch.Tensor]] = {
    "identity": identity,
    "sigmoid": torch.sigmoid,
    "tanh": torch.tanh,
    "relu": torch.relu,
    "threshold": threshold,
}


def transfer(name: str) -> Callable[[torch.Tensor], torch.Tensor]:
    """The transfer function ``F`` of eq. 4.4 by name (identity, sigmoid, tanh, relu, threshold)."""
    try:
        return TRANSFER[name]
    except KeyError:
        raise ValueError(f"unknown transfer function {name!r}; choose one of {sorted(TRANSFER)}") from None


def check_tensor(name: str, x: torch.Tensor, last_dims: Sequence[int] | None = None, finite: bool = True) -> torch.Tensor:
    """Raise ValueError naming ``name`` if ``x`` is not a tensor, has the wrong trailing shape or
    NaNs (the last only while :func:`checks_enabled`)."""
    if not isinstance(x, torch.Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    if last_dims is not None:
        k = len(last_dims)
        if x.dim() < k or tuple(x.shape[x.dim() - k:]) != tuple(last_dims):
            raise ValueError(f"{name} must end in shape {tuple(last_dims)}, got {tuple(x.shape)}")
    if finite and x.is_floating_point() and checks_enabled(x) and not torch.isfinite(x).all():
        raise ValueError(f"{name} contains NaN or infinite values")
    return x


def check_floating(name: str, x: torch.Tensor) -> torch.Tensor:
    """Raise ValueError naming ``name`` if the activity ``x`` is not floating point (an integer or
    boolean map would be summed with integer arithmetic or refused deep inside torch)."""
    if not (x.is_floating_point() or x.is_complex()):
        raise ValueError(f"{name} has dtype {x.dtype}: activity must be floating point (e.g. x.float())")
    return x


def check_participants(block: str, P: int, xb: torch.Tensor, given: Sequence[int]) -> None:
    """Raise ValueError naming ``block`` unless the batched input ``xb`` ``(P', B, n)`` has the
    ``P`` participants of the block's weights (or the weights are shared, ``P = 1``); ``given`` is
    the input's shape as the caller passed it (1-D and 2-D inputs are one participant)."""
    Px = xb.shape[0]
    if P == Px or P == 1:
        return
    given = tuple(given)
    if len(given) < 3:
        what = "one trial of one participant" if len(given) == 1 else f"{given[0]} trials of one participant"
        raise ValueError(f"{block}: a {len(given)}-D input {given} is {what}, but the block holds the "
                         f"weights of {P} participants: give ({P}, trials, {xb.shape[-1]})")
    raise ValueError(f"{block}: input has {Px} participant{'' if Px == 1 else 's'}, the weights {P}")


def participants_weight(block: str, weight: torch.Tensor, xb: torch.Tensor, given: Sequence[int]) -> torch.Tensor:
    """``weight`` ``(P, ...)`` ready for the batched input ``xb`` ``(P', B, n)`` of ``block``
    (:func:`check_participants`): a shared ``(1, ...)`` weight expanded to ``P'``, cast to the
    input's dtype (a block computes in its input's dtype; the buffer keeps its own)."""
    check_participants(block, weight.shape[0], xb, given)
    if weight.shape[0] == 1 and xb.shape[0] != 1:
        weight = weight.expand(xb.shape[0], *weight.shape[1:])
    return weight if weight.dtype == xb.dtype else weight.to(xb.dtype)


def as_batched(x: torch.Tensor, n: int, name: str = "input") -> tuple[torch.Tensor, bool]:
    """View ``x`` as ``(P, B, n)``.

    Accepts ``(n,)`` (one trial, one participant), ``(B, n)`` (P = 1) or ``(P, B, n)``. Returns the
    view and whether the caller should squeeze the participant axis away again.
    """
    check_tensor(name, x, (n,))
    return as_batched_shape(x, n, name)


def as_batched_shape(x: torch.Tensor, n: int, name: str) -> tuple[torch.Tensor, bool]:
    """:func:`as_batched` without the check of the values (the fast path of the blocks,
    :mod:`neuroimagery.nn.readout`, checks them once per batch)."""
    check_floating(name, x)
    if x.dim() == 1:
        return x.reshape(1, 1, n), True
    if x.dim() == 2:
        return x.unsqueeze(0), True
    if x.dim() == 3:
        return x, False
    raise ValueError(f"{name} must have shape (n,), (B, n) or (P, B, n) with n={n}, got {tuple(x.shape)}")


def gaussian_bump(centres: torch.Tensor, coords: torch.Tensor, sigma: float | torch.Tensor, amplitude: float = 1.0) -> torch.Tensor:
    """Gaussian tuning curves (eq. 4.1, noise-free mean response).

    ``centres``: ``(..., D)`` values to encode; ``coords``: ``(n, D)`` preferred values of the
    units. Returns ``(..., n)`` activity ``A exp(-|c - x|^2 / (2 sigma^2))``.
    """
    d2 = ((centres.unsqueeze(-2) - coords) ** 2).sum(-1)
    return amplitude * torch.exp(-d2 / (2.0 * torch.as_tensor(sigma, dtype=d2.dtype, device=d2.device) ** 2))


def grid_coords(shape: Sequence[int]) -> torch.Tensor:
    """Integer grid coordinates ``(units, D)`` of a 1-D or 2-D map."""
    axes = [torch.arange(int(n), dtype=torch.float32) for n in shape]
    g = torch.meshgrid(*axes, indexing="ij")
    return torch.stack([x.reshape(-1) for x in g], dim=-1)


def squared_norms(w: torch.Tensor, rows: int = 256) -> torch.Tensor:
    """``(w * w).sum(-1)`` computed a block of rows at a time: the same numbers (each row's sum
    is its own reduction) without a temporary the size of ``w``."""
    flat = w.reshape(-1, w.shape[-1])
    return torch.cat([(b * b).sum(-1) for b in flat.split(rows)]).reshape(w.shape[:-1])


TILE = 64  # side of the square tiles a large transpose is copied in (a 64 x 64 float tile: 16 KiB)


def transpose_into(out: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """``out[..., i, j] = x[..., j, i]``, copied in ``TILE`` x ``TILE`` tiles (each read and written
    while it is in the cache; one strided copy of a large matrix misses the cache on nearly every
    element): the values of ``x.transpose(-1, -2)``, a copy, nothing computed. Returns ``out``."""
    a, b = x.shape[-2:]
    if out.shape != (*x.shape[:-2], b, a):
        raise ValueError(f"transpose_into: out {tuple(out.shape)} does not fit x {tuple(x.shape)}")
    if a * b < 4 * TILE * TILE:
        return out.copy_(x.transpose(-1, -2))
    for i in range(0, b, TILE):
        for j in range(0, a, TILE):
            out[..., i:i + TILE, j:j + TILE] = x[..., j:j + TILE, i:i + TILE].transpose(-1, -2)
    return out


def transposed_copy(x: torch.Tensor) -> torch.Tensor:
    """``x.transpose(-1, -2).contiguous()`` as a new tensor, copied in tiles (:func:`transpose_into`)."""
    return transpose_into(x.new_empty(*x.shape[:-2], x.shape[-1], x.shape[-2]), x)


def gain_field(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Gain field (eq. 6.1, 6.9): outer product of two 1-D population codes.

    ``a``: ``(..., n)``, ``b``: ``(..., m)`` -> ``(..., n, m)`` with entry ``a_i * b_j``.
    """
    return a.unsqueeze(-1) * b.unsqueeze(-2)


def softmax_probabilities(x: torch.Tensor, temperature: float) -> torch.Tensor:
    """Boltzmann probabilities ``exp(x_i / tau) / sum_k exp(x_k / tau)`` (eq. 6.3, 6.11, 7.7)."""
    check_rate("temperature", temperature, open_low=True)
    return torch.softmax(x / temperature, dim=-1)


def softmax_select(x: torch.Tensor, temperature: float, generators: Sequence[torch.Generator] | None = None,
                   uniforms: torch.Tensor | None = None) -> torch.Tensor:
    """Draw one index per row of ``x`` (``(P, B, n)`` or ``(B, n)``) with softmax probabilities.

    Randomness comes either from ``uniforms`` (``x.shape[:-1]`` numbers in [0, 1)) or from one
    generator per participant (first axis). Returns long indices of shape ``x.shape[:-1]``.
    """
    p = softmax_probabilities(x, temperature)
    if uniforms is None:
        if generators is None:
            raise ValueError("softmax_select needs generators or uniforms")
        if x.dim() == 3:
            if len(generators) != x.shape[0]:
                raise ValueError(f"softmax_select: {len(generators)} generators for {x.shape[0]} participants")
            uniforms = torch.stack([torch.rand(x.shape[1], generator=g) for g in generators])
        else:
            uniforms = torch.rand(x.shape[:-1], generator=generators[0])
    cdf = p.cumsum(-1)
    idx = (cdf < uniforms.unsqueeze(-1).to(device=cdf.device, dtype=cdf.dtype)).sum(-1)
    return idx.clamp_max(x.shape[-1] - 1)


def user_error(msg: str) -> UserInputError:
    """Shorthand used by loaders for a user's mistake."""
    return UserInputError(msg)


_SETTINGS: list[int] = []  # thread counts of the intra_op_threads blocks now open, outermost first


@contextlib.contextmanager
def intra_op_threads(n: int, cap: bool = False):
    """Run the block on ``n`` torch intra-op threads (with ``cap``: at most ``n``, never more than
    are set now), restoring the previous setting afterwards. Loops of small products run faster on
    one thread than with several threads handing work to each other."""
    before = torch.get_num_threads()
    now = min(before, n) if cap else n
    torch.set_num_threads(now)
    _SETTINGS.append(now)
    try:
        yield
    finally:
        _SETTINGS.pop()
        torch.set_num_threads(before)


def thread_budget() -> int:
    """The threads the outermost :func:`intra_op_threads` block allows (a run's ``threads``, or the
    free cores measured at its start), else torch's current count: what independent work, such as
    the draws of several participants' generators, may run side by side even where an inner block
    keeps each product on one thread."""
    return _SETTINGS[0] if _SETTINGS else torch.get_num_threads()
