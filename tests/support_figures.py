"""The overlap check of figures: every pair of visible texts of a saved figure (titles, axis and
tick labels, legends, annotations) measured with matplotlib's renderer must not overlap, and no
text may run off the figure."""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import matplotlib
from matplotlib.figure import Figure
from matplotlib.text import Text


def text_overlaps(fig, pad: float = 0.5) -> list[str]:
    """Pairs of visible, non-empty texts of ``fig`` whose bounding boxes (display pixels) overlap
    by more than ``pad`` pixels each way."""
    fig.canvas.draw()  # positions at the figure's own dpi, as the renderer below measures them
    renderer = fig.canvas.get_renderer()
    hidden = set()  # tick labels the axis does not draw (their tick lies outside the view)
    for ax in fig.axes:
        for axis, (lo, hi) in ((ax.xaxis, sorted(ax.get_xlim())), (ax.yaxis, sorted(ax.get_ylim()))):
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not lo - 1e-9 * (hi - lo) <= tick.get_loc() <= hi + 1e-9 * (hi - lo):
                    hidden.update({id(tick.label1), id(tick.label2)})
    texts = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip() and id(t) not in hidden]
    boxes = [(t, t.get_window_extent(renderer)) for t in texts]
    W, H = fig.canvas.get_width_height()
    out = [f"{t.get_text()!r} runs off the figure" for t, b in boxes
           if b.x0 < -pad or b.y0 < -pad or b.x1 > W + pad or b.y1 > H + pad]
    for i, (ta, a) in enumerate(boxes):
        for tb, b in boxes[i + 1:]:
            if a.x0 < b.x1 - pad and b.x0 < a.x1 - pad and a.y0 < b.y1 - pad and b.y0 < a.y1 - pad:
                out.append(f"{ta.get_text()!r} overlaps {tb.get_text()!r}")
    return out


@contextmanager
def checking_overlaps():
    """Within the block every ``Figure.savefig`` first records its text overlaps; yields the dict
    ``{file name: [overlaps]}`` of the figures that had some."""
    found: dict[str, list[str]] = {}
    original = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        result = original(self, fname, *args, **kwargs)  # after the layout the figure is saved with
        bad = text_overlaps(self)
        if bad:
            found[Path(str(fname)).name] = bad
        return result

    Figure.savefig = savefig
    try:
        yield found
    finally:
        Figure.savefig = original
    assert matplotlib.get_backend().lower() == "agg"
