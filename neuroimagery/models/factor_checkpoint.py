"""Compact checkpoints for the chapter-5 models (Experiments 1 and 2): their large trained weights
are fixed functions of the initial weights and a few small factors, so a checkpoint stores the
factors and loading forms the weights again with the trainer's own functions, bit for bit."""
from __future__ import annotations

import torch

from ..nn.functional import intra_op_threads
from ..nn.hebbian_closed_form import hebbian_shared, rebuild_indexed
from ..nn.som import rebuild_windowed


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
        the same functions, so they come back bit for bit; ``probe`` (each weight's first and last
        row) checks that on load. Needs a model trained by :meth:`fit` in this process."""
        fx = getattr(self, "_factors", None)
        if not fx:
            raise ValueError("compact_state() needs a model trained by fit() in this process; use state_dict()")
        state = self.state_dict()
        return {"format": self.CHECKPOINT_FORMAT, "seed": self.seed, "participants": self.c1.participants,
                "state": {k: v for k, v in state.items() if k not in fx}, "factors": fx,
                "probe": {k: state[k][:, [0, -1]].clone() for k in fx}}

    @torch.no_grad()
    def load_compact_state(self, ck: dict) -> None:
        """Load a :meth:`compact_state` into this *freshly built* model (built with the checkpoint's
        ``seed`` and participants, and the experiment settings it was trained with: the initial
        weights are the starting point of every formula). Raises ``ValueError`` on another format
        or when the rebuilt weights do not match the saved probe rows."""
        fmt = ck.get("format") if isinstance(ck, dict) else None
        if fmt != self.CHECKPOINT_FORMAT:
            raise ValueError(f"unknown checkpoint format {fmt!r} ({type(self).__name__} reads {self.CHECKPOINT_FORMAT!r})")
        if ck["seed"] != self.seed or ck["participants"] != self.c1.participants:
            raise ValueError(f"checkpoint of seed {ck['seed']}, {ck['participants']} participants loaded into a model "
                             f"of seed {self.seed}, {self.c1.participants} participants (its initial weights differ)")
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
        bad = [k for k, v in ck["probe"].items() if not torch.equal(state[k][:, [0, -1]], v)]
        if bad:
            raise ValueError(f"the weights rebuilt from the checkpoint's factors differ from the trained ones ({', '.join(bad)}): "
                             "was it trained with other experiment settings (e.g. init_high, som_cutoff)?")
