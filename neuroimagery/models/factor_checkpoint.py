"""Compact checkpoints for the chapter-5 models (Experiments 1 and 2): their large trained weights
are fixed functions of the initial weights and a few small factors, so a checkpoint stores the
factors and loading forms the weights again with the trainer's own functions: bit for bit on the
CPU and thread count they were trained on (the same kernels on the same shapes), within float
rounding elsewhere (another CPU's BLAS may sum the same products in another order)."""
from __future__ import annotations

import torch

from ..nn.functional import intra_op_threads
from ..nn.hebbian_closed_form import hebbian_shared, rebuild_indexed
from ..nn.numerics import cast_bound, rounding_bound
from ..nn.som_windowed import rebuild_windowed

PROBE_ROWS = [0, -1]  # the rows of each rebuilt weight checked on load


@torch.no_grad()
def probe_bound(factors: dict, w0: torch.Tensor, saved: torch.Tensor) -> torch.Tensor:
    """The most the probe rows ``PROBE_ROWS`` of a weight rebuilt from ``factors`` and its initial
    rows ``w0`` may differ from the ``saved`` ones when only the rounding differs: the
    :func:`~neuroimagery.nn.numerics.rounding_bound` of the sums that form them, ``w = scale w0 +
    sum_n coef_n x_n`` (SOMs, ``N + 1`` terms) or ``w = a w0 + sum_k post_k C_k`` (Hebbian, ``K + 1``),
    in float32; the shared-sequence Hebbian form works in float64, where each of its terms passes
    through at most ``2 T + 5`` roundings (``T`` factors of its decay, 3 more products, ``T`` sums
    over the steps, 2 to combine), then rounds to float32 (one more ulp)."""
    d, r = torch.float64, PROBE_ROWS
    w0 = w0.to(d).abs()
    kind = factors["kind"]
    if kind == "som_windowed":
        X = factors["patterns"].to(d).abs()
        coef = factors["coef"][:, r].to(d).abs()
        prod = torch.einsum("pkn,ni->pki" if X.dim() == 2 else "pkn,pni->pki", coef, X)
        return rounding_bound(factors["scale"][:, r].to(d).abs().unsqueeze(-1) * w0 + prod, coef.shape[-1] + 1)
    if kind == "hebbian_indexed":
        C = factors["C"].to(d).abs()
        prod = torch.einsum("ko,pki->poi", factors["post_set"][:, r].to(d).abs(), C)
        return rounding_bound(factors["a"].to(d).abs().unsqueeze(1) * w0 + prod, C.shape[1] + 1)
    if kind == "hebbian_shared":
        pre, post, eta = factors["pre"].to(d), factors["post"][:, r].to(d), float(factors["eta"])
        keep = (1.0 - eta * pre).abs()  # the decays and suffix products of hebbian_shared, in absolute value
        rev = torch.cumprod(torch.flip(keep, [0]), 0)
        suffix = torch.cat([torch.flip(rev, [0])[1:], torch.ones_like(keep[:1])], 0)
        mag = rev[-1] * w0 + (post.abs().T @ (abs(eta) * pre.abs() * suffix)).unsqueeze(0)
        T = pre.shape[0]
        return rounding_bound(mag, 2 * T + 5, d) + cast_bound(saved.to(d))
    raise ValueError(f"unknown factor kind {kind!r}")


class FactorCheckpoint:
    """Compact checkpoints of a chapter-5 model whose :meth:`fit` records, in ``self._factors``
    (key: the ``state_dict`` entry), what each large trained weight was formed from. The model
    has ``e`` (with ``som_threads``), ``seed`` and a connection ``c1``; each subclass names its
    ``CHECKPOINT_FORMAT``. Weights without factors are saved in full."""

    def compact_state(self) -> dict:
        """The trained state in compact form (``self.CHECKPOINT_FORMAT``): every small tensor of
        ``state_dict()`` as it is, and for each large weight what the trainer formed it from (the
        SOMs' scale factors and coefficients over their pattern sets, the Hebbian closed forms'
        decay and per-pattern sums, the shared-sequence Hebbian connections' training sequences). The initial weights are not
        saved: they are drawn again from ``seed``. :meth:`load_compact_state` forms the weights by
        the same functions, so they come back bit for bit on the same CPU and thread count;
        ``probe`` (each weight's first and last row) checks them on load, to within float rounding.
        Needs a model trained by :meth:`fit` in this process."""
        fx = getattr(self, "_factors", None)
        if not fx:
            raise ValueError("compact_state() needs a model trained by fit() in this process; use state_dict()")
        state = self.state_dict()
        return {"format": self.CHECKPOINT_FORMAT, "seed": self.seed, "participants": self.c1.participants,
                "state": {k: v for k, v in state.items() if k not in fx}, "factors": fx,
                "probe": {k: state[k][:, PROBE_ROWS].clone() for k in fx}}

    @torch.no_grad()
    def load_compact_state(self, ck: dict) -> None:
        """Load a :meth:`compact_state` into this *freshly built* model (built with the checkpoint's
        ``seed`` and participants, and the experiment settings it was trained with: the initial
        weights are the starting point of every formula). Raises ``ValueError`` on another format
        or when the rebuilt weights differ from the saved probe rows by more than float rounding
        (:func:`probe_bound`: the bound of the sums that form them, as another CPU's BLAS or
        another thread count may round them)."""
        fmt = ck.get("format") if isinstance(ck, dict) else None
        if fmt != self.CHECKPOINT_FORMAT:
            raise ValueError(f"unknown checkpoint format {fmt!r} ({type(self).__name__} reads {self.CHECKPOINT_FORMAT!r})")
        if ck["seed"] != self.seed or ck["participants"] != self.c1.participants:
            raise ValueError(f"checkpoint of seed {ck['seed']}, {ck['participants']} participants loaded into a model "
                             f"of seed {self.seed}, {self.c1.participants} participants (its initial weights differ)")
        state = self.state_dict()
        init = {k: state[k][:, PROBE_ROWS] for k in ck["factors"]}  # the initial weights' rows
        for key, f in ck["factors"].items():
            mod = self.get_submodule(key.rsplit(".", 1)[0])
            if f["kind"] == "som_windowed":  # the trainer's threads (the final product ran inside fit_soms)
                with intra_op_threads(self.e.som_threads, cap=True):
                    rebuild_windowed(mod, f)
            elif f["kind"] == "hebbian_indexed":
                mod.weight.copy_(rebuild_indexed(mod.weight, f))
            elif f["kind"] == "hebbian_shared":
                mod.weight.copy_(hebbian_shared(mod.weight, f["pre"], f["post"], f["eta"]))
            else:
                raise ValueError(f"unknown factor kind {f['kind']!r} for {key}")
        res = self.load_state_dict(ck["state"], strict=False)
        if set(res.missing_keys) != set(ck["factors"]) or res.unexpected_keys:
            raise ValueError(f"checkpoint state does not fit the model: missing {sorted(set(res.missing_keys) - set(ck['factors']))}, "
                             f"unexpected {res.unexpected_keys}")
        state = self.state_dict()
        off = {k: (state[k][:, PROBE_ROWS].double() - v.double()).abs() for k, v in ck["probe"].items()}
        bad = [k for k, v in ck["probe"].items() if not bool((off[k] <= probe_bound(ck["factors"][k], init[k], v)).all())]
        if bad:
            raise ValueError(f"the weights rebuilt from the checkpoint's factors differ from the trained ones by more than "
                             f"float rounding ({', '.join(bad)}): was it trained with other experiment settings "
                             "(e.g. init_high, som_cutoff)?")
