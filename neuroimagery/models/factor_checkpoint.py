"""Compact checkpoints for the chapter-5 models (Experiments 1 and 2): their large trained weights
are fixed functions of the initial weights and a few small factors, so a checkpoint stores the
factors (each learner's ``learnt_factors``, recorded by the form of its rule that trained it,
:mod:`neuroimagery.nn.forms`) and loading forms the weights again with that form's own functions: bit for bit on the
CPU and thread count they were trained on (the same kernels on the same shapes), within float
rounding elsewhere (another CPU's BLAS may sum the same products in another order)."""
from __future__ import annotations

import contextlib

import torch

from ..nn import SOM, forms
from ..nn.functional import intra_op_threads

PROBE_ROWS = [0, -1]  # the rows of each rebuilt weight checked on load


def probe_bound(factors: dict, w0: torch.Tensor, saved: torch.Tensor) -> torch.Tensor:
    """The most the probe rows ``PROBE_ROWS`` of a weight rebuilt from ``factors`` and its initial
    rows ``w0`` may differ from the ``saved`` ones when only the rounding differs: the bound of
    the form that recorded the factors (:meth:`neuroimagery.nn.forms.Form.bound`, the
    :func:`~neuroimagery.nn.numerics.rounding_bound` of the sums that form them)."""
    return forms.bound(factors, w0, saved, PROBE_ROWS)


def learnt_factors(model) -> dict:
    """What each trained weight of ``model`` was formed from (key: its ``state_dict`` entry), as
    the forms that trained its connections and maps recorded it; weights without factors are
    saved in full."""
    return {f"{name}.weight": m.learnt_factors for name, m in model.named_modules()
            if getattr(m, "learnt_factors", None) is not None}


class FactorCheckpoint:
    """Compact checkpoints of a chapter-5 model whose :meth:`fit` keeps, in ``self._factors``
    (:func:`learnt_factors`), what each large trained weight was formed from. The model
    has ``e`` (with ``som.threads``), ``seed`` and a connection ``c1``; each subclass names its
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
            try:
                form = forms.factor_form(f)
            except ValueError as err:
                raise ValueError(f"{err} for {key}") from None
            # a map's trainer ran on the SOM threads (fit_soms): its final product is rebuilt there
            threads = intra_op_threads(self.e.som.threads, cap=True) if isinstance(mod, SOM) else contextlib.nullcontext()
            with threads:
                form.rebuild(mod, f)
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
                             "(e.g. init_high, som.cutoff)?")
