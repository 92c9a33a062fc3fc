"""Measurements shared by the Experiment 3 and 4 contract tests (docs/contracts.md)."""
from __future__ import annotations

import torch

from neuroimagery.vision.edges import iou, rotate

# Where in the plain text of the thesis each Exp 3-4 contract's quoted sentence stands (line numbers of
# the text the project was built from; docs/contracts.md quotes the sentence with its section, which any
# copy of the thesis has).
THESIS_LINES = {
    "X3.1": ('1027-1030', '1033'),
    "X3.2": ('1025',),
    "X3.3": ('1017',),
    "X3.4": ('984',),
    "X3.5": ('964',),
    "X3.6": ('1063-1065',),
    "X3.7": ('1067', '1015'),
    "X3.8": ('984',),
    "X3.9": ('1067',),
    "X3.10": ('1067', '1015'),
    "X3.11": ('1061',),
    "X3.12": ('1065',),
    "X3.13": ('913-915',),
    "X4.1": ('1226-1230', '1232'),
    "X4.2": ('1225', '1232-1234'),
    "X4.3": ('1234',),
    "X4.4": ('1176',),
    "X4.5": ('1166',),
    "X4.6": ('1214', '1252'),
    "X4.7": ('1187',),
    "X4.8": ('1121', '1147'),
    "X4.10": ('1199',),
    "X4.11": ('1265', '1269'),
    "X4.12": ('1199', '1291'),
    "X4.13": ('1176-1181', '1291'),
    "X4.14": ('913-915', '1160'),
}


def forward_fn(trained, move: int):
    """One forward-model step of ``trained.model`` with the same move for every row of a
    ``(P or 1, B, units)`` batch (the shape probes of X3.7 / X4.6)."""
    m, P = trained.model, trained.model.participants

    def fn(x):
        x = x.expand(P, -1, -1) if x.shape[0] == 1 else x
        return m.forward_step(x, torch.full(x.shape[:2], move, dtype=torch.long))
    return fn


def item_rows(bank, appearance=None):
    """Rows of ``bank`` as (row, object, angle, appearance)."""
    return [(i, o, float(a), ap) for i, (o, a, ap) in enumerate(bank.items) if appearance is None or ap == appearance]


def forward_model_shape(step_fn, maps: torch.Tensor, step_deg: float, size: int, steps: int = 2) -> dict:
    """X3.7 / X4.6: IoU of the imagined map after k steps with the true rotation at k steps and at
    k +- 1 steps, and the active-unit ratio at k = 1 (means over images and participants)."""
    x = maps.reshape(-1, size, size)
    cur = maps.unsqueeze(0)
    out = {}
    for k in range(1, steps + 1):
        cur = step_fn(cur)
        img = cur.reshape(cur.shape[0], -1, size, size)
        truth = {j: rotate(x, j * step_deg).unsqueeze(0) for j in (k - 1, k, k + 1)}
        out[k] = {j: float(iou(img, t).mean()) for j, t in truth.items()}
        if k == 1:
            out["ratio"] = float(img.sum((-2, -1)).mean() / truth[1].sum((-2, -1)).mean())
    return out


def model_rule_rate(som, maps: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """X3.1 / X4.1: one step of the configured map's own rule (a copy of ``som``, trained), on the
    first training image with its posture as the winner: ``|w' - w|_1 / |x' - w|_1`` of the winner's
    prototype per participant, ``x'`` the image as the rule sees it (scaled to sum 1 by default)."""
    import copy

    s = copy.deepcopy(som).train()
    P = s.weight.shape[0]
    x, win = maps[:1].expand(P, -1).contiguous(), labels[:1].expand(P).contiguous()
    w0 = s.weight[:, int(win[0])].clone()
    s.step(x, win)
    xs = s.rule.scale_input(x)
    return (s.weight[:, int(win[0])] - w0).abs().sum(-1) / (xs - w0).abs().sum(-1)


def _blur(x: torch.Tensor, sigma: float, size: int) -> torch.Tensor:
    """Gaussian blur of maps ``(..., size*size)`` (zero outside the map)."""
    r = int(3 * sigma + 0.5)
    k = torch.exp(-torch.arange(-r, r + 1, dtype=torch.float32) ** 2 / (2 * sigma ** 2))
    k = k / k.sum()
    shp = x.shape
    img = x.reshape(-1, 1, size, size).float()
    img = torch.nn.functional.conv2d(img, k.view(1, 1, 1, -1), padding=(0, r))
    img = torch.nn.functional.conv2d(img, k.view(1, 1, -1, 1), padding=(r, 0))
    return img.reshape(shp)


def shape_and_detail(step_fn, maps: torch.Tensor, step_deg: float, size: int, steps: int = 3) -> dict:
    """X3.9 / X3.10: after k = 1..steps imagined steps, the cosine similarity of the imagined map and the
    true rotation both blurred by a Gaussian of 2 units (shape), and the imagined map's fine-scale share
    of energy ``|x - G1 x|^2 / |x|^2`` divided by the true rotation's (detail); means over images and
    participants."""
    x = maps.reshape(-1, size, size)
    cur = maps.unsqueeze(0)
    out = {}
    def detail(m):
        m = m.float()
        return ((m - _blur(m, 1.0, size)) ** 2).sum(-1) / (m ** 2).sum(-1).clamp_min(1e-12)
    for k in range(1, steps + 1):
        cur = step_fn(cur)
        truth = rotate(x, k * step_deg).reshape(1, -1, size * size).float()
        a, b = _blur(cur.float(), 2.0, size), _blur(truth, 2.0, size)
        cos = (a * b).sum(-1) / (a.norm(dim=-1) * b.norm(dim=-1)).clamp_min(1e-12)
        out[k] = {"shape": float(cos.mean()), "detail": float(detail(cur).mean() / detail(truth).mean())}
    return out


def entropy_bits(p: torch.Tensor) -> torch.Tensor:
    """Entropy in bits of non-negative codes ``(..., units)`` scaled to sum 1."""
    q = p / p.sum(-1, keepdim=True).clamp_min(1e-12)
    return -(q * torch.log2(q.clamp_min(1e-12))).sum(-1)


def assert_supervised_rate(trained, soms, angles, eta: float, contract: str) -> None:
    """X3.1 / X4.1: each configured posture map's one step of its own rule moves the winner's
    prototype by between 0.5 eta and 2 eta of its distance to the image (eta 0.1 stated)."""
    bank = trained.bank(trained.e.train_set)
    labels = bank.angle_labels(angles)
    for som in soms:
        r = model_rule_rate(som, bank.maps, labels)
        print(f"{contract} {som.name} relative change per step {[round(float(v), 4) for v in r]} (eta {eta})")
        assert bool(((r >= 0.5 * 0.1) & (r <= 2 * 0.1)).all())


def assert_looks_vary(trained, soms, angles, winner, contract: str) -> None:
    """X3.13 / X4.14: two looks at the training items differ for at least half of them, and each
    configured posture map still reads the fresh look's posture (``winner``: a map's output -> the
    winning unit) for at least 0.95 of the items."""
    e, m = trained.e, trained.model
    looks = trained.looks(e.train_set)
    differ = float((looks[0] != looks[1]).any(-1).float().mean())
    labels = trained.bank(e.train_set).angle_labels(angles)
    x = looks[1].unsqueeze(0).expand(m.participants, -1, -1)
    acc = [float((winner(m.posture(som, x)) == labels).float().mean()) for som in soms]
    print(f"{contract} items whose two looks differ {differ:.3f}; {' / '.join(s.name for s in soms)} right on fresh looks {acc}")
    assert differ >= 0.5 and min(acc) >= 0.95
