"""``report.md``: a run's results beside the thesis's targets, with the figures embedded."""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from ..core.files import write_text


def fmt(v: Any, pct: bool = False) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return f"{100 * v:.1f} %" if pct else (f"{v:.3g}" if isinstance(v, float) else str(v))
    return str(v)


def fmt_p(v: float | None) -> str:
    """A p value for a report: two significant digits, ``< 1e-16`` below double precision's
    resolution of 1 - p (never a bare 0), ``-`` when there is none."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return "< 1e-16" if v < 1e-16 else f"{v:.2g}"


def cell(x: Any) -> str:
    """One table cell: formatted (:func:`fmt`), its pipes escaped so that Markdown keeps the
    columns (``RT rises with \\|disparity\\|``), line breaks made spaces."""
    text = x if isinstance(x, str) else fmt(x)
    return re.sub(r"(?<!\\)\|", r"\\|", text.replace("\n", " "))


EQUIVALENCE_NOTE = (
    "A claim of no effect ('~0') is tested by equivalence: two one-sided t-tests (TOST) against -B and +B, "
    "the bound B in the 'expected' column, fixed by a rule from the measure's unit before measuring "
    "(docs/choices.md, 'Statistics in the reports'); its p is the larger one-sided p, Holm-corrected with the rest. It reads "
    "'equivalent within ±B' when p (Holm) < 0.05 and 'not shown' otherwise: a large p of a difference test "
    "is never read as no effect.")

DEGENERATE_NOTE = (
    "d_z marked '(degenerate)': the participants' values vary by less than a tenth of their mean (|d_z| > 10). "
    "The simulated participants differ only in their initial weights and the order of their training samples, "
    "so they are near copies; d_z then measures how alike they are, not how large the effect is. Read the "
    "mean difference and its interval instead.")


def _p_after(p) -> str:
    t = fmt_p(p)
    return "not computable (every participant alike)" if t == "-" else t if t.startswith("<") else f"= {t}"


class Report:
    """Builds a markdown report section by section; ``write(path)`` saves it."""

    def __init__(self, title: str) -> None:
        self.lines: list[str] = [f"# {title}", ""]

    def h(self, text: str, level: int = 2) -> "Report":
        self.lines += ["#" * level + " " + text, ""]
        return self

    def p(self, text: str) -> "Report":
        self.lines += [text, ""]
        return self

    def bullets(self, items) -> "Report":
        """A list; empty items are left out (a list with none is not written)."""
        items = [str(x).strip() for x in items if x is not None and str(x).strip()]
        if items:
            self.lines += [f"- {x}" for x in items] + [""]
        return self

    def table(self, header: list[str], rows: list[list[Any]]) -> "Report":
        """A table; every row is given ``len(header)`` cells (pipes escaped, :func:`cell`)."""
        self.lines.append("| " + " | ".join(cell(h) for h in header) + " |")
        self.lines.append("|" + "|".join("---" for _ in header) + "|")
        for r in rows:
            r = list(r)
            if len(r) != len(header):
                raise ValueError(f"table row of {len(r)} cells under a header of {len(header)}: {r!r}")
            self.lines.append("| " + " | ".join(cell(x) for x in r) + " |")
        self.lines.append("")
        return self

    def targets(self, rows: list[tuple[str, Any, Any, bool]]) -> "Report":
        """Rows of (measure, this run, thesis, as percentage?) with the difference."""
        out = []
        for name, ours, thesis, pct in rows:
            diff = None
            if isinstance(ours, (int, float)) and isinstance(thesis, (int, float)):
                diff = ours - thesis
            d = "-" if diff is None else (f"{100 * diff:+.1f} pts" if pct else f"{diff:+.3g}")
            out.append([name, fmt(ours, pct), fmt(thesis, pct), d])
        return self.table(["measure", "this run", "thesis", "difference"], out)

    def chance_warning(self, summary: dict) -> "Report":
        """At the top of a report on a user's stimuli: say so when the participants' correct rates
        on them are not above chance (``summary["custom_vs_chance"]``)."""
        c = summary.get("custom_vs_chance")
        if c and not c["above_chance"]:
            p = fmt_p(c["p_greater"])
            self.p(f"**Warning: on your stimuli (test `custom`) the model answers at chance.** Mean correct rate "
                   f"{100 * c['mean_correct']:.1f} % over {c['n']} participants; one-sided t-test of their rates "
                   f"against 50 %: p = {p}. Its other numbers on these stimuli say little.")
        return self

    def user_stimuli(self, summary: dict, folder: str, replaced: str, trained_on: str) -> "Report":
        """The section on a user's stimulus folder (test ``custom``): where it came from, the
        sentence ``replaced`` (which built-in set it replaced), the sentence ``trained_on`` (what
        the model was trained on), and the one-sided test of the
        participants' correct rates against chance (``summary["custom_vs_chance"]``)."""
        self.h("Your stimuli")
        self.p(f"Folder `{folder}`, tested as test `custom`. {replaced} {trained_on}")
        c = summary.get("custom_vs_chance")
        if c:
            verdict = "above chance" if c["above_chance"] else "**not above chance**"
            t = "-" if c.get("t") is None else f"{c['t']:.3g}"
            self.p(f"Above chance? Mean correct rate {100 * c['mean_correct']:.1f} % over {c['n']} participants; "
                   f"one-sided one-sample t-test of their rates against 50 %: t = {t}, p {_p_after(c['p_greater'])}: "
                   f"{verdict} (alpha 0.05).")
        return self

    def effects(self, rows: list[dict], intro: str | None = None, equivalence: str | None = None) -> "Report":
        """The effects table of :func:`neuroimagery.analysis.summary.effect` rows: the participant is
        the unit (paired t-tests over participants, or one-sample t-tests of their slopes), a claim
        of no effect an equivalence test (TOST) within a bound fixed by a rule (docs/choices.md),
        Holm's correction over the table's family; ``intro`` replaces the paragraph that says so."""
        self.p(intro or "Each effect is tested with the simulated participant as the unit (statsmodels): a paired t-test "
               "over the participants' mean RT or correct rate (value = mean difference, first condition minus "
               "the second, with its 95 % interval), or a one-sample t-test of their RT-disparity slopes (value = "
               "mean slope per degree). d_z is the standardised effect (mean over the standard deviation of the "
               "participants' differences or slopes) with its 95 % interval from the noncentral t distribution. "
               "p is two-sided; p (Holm) applies Holm's correction over the rows of this table, the report's "
               "family of effects. 'yes': the expected sign with p (Holm) < 0.05.")
        if any(e["expected"] == "~0" for e in rows):
            self.p(equivalence or EQUIVALENCE_NOTE)
        ci = lambda c: "-" if not c else f"[{c[0]:.3g}, {c[1]:.3g}]"  # noqa: E731

        def expected(e):
            b = e.get("bound")
            return e["expected"] if e["expected"] != "~0" or b is None else f"~0 (±{b:.3g})"

        def verdict(e):
            if e["expected"] == "~0":
                b = e.get("bound")
                if b is None:
                    return "not shown (no bound set)"
                return f"equivalent within ±{b:.3g}" if e["holds"] else "not shown"
            return "-" if e["holds"] is None else ("yes" if e["holds"] else "**no**")

        def dz(e):
            return fmt(e.get("d_z")) + (" (degenerate)" if e.get("d_z_degenerate") else "")

        self.table(["effect", "expected", "value", "95 % CI", "d_z", "d_z 95 % CI", "n", "p", "p (Holm)", "holds"],
                   [[e["effect"], expected(e), fmt(e["value"]), ci(e["ci95"]), dz(e), ci(e.get("d_z_ci95")), e["n"],
                     fmt_p(e["p"]), fmt_p(e.get("p_holm")), verdict(e)] for e in rows])
        if any(e.get("d_z_degenerate") for e in rows):
            self.p(DEGENERATE_NOTE)
        untested = [e for e in rows if e.get("untested")]
        if untested:
            self.p("Rows without a test ('-'): " + "; ".join(f"{e['effect']}: {e['untested']}" for e in untested) + ".")
        return self

    def figures(self, run_root: str | Path, paths, errorbars: str = "Error bars: SEM over participants") -> "Report":
        """The run's figures in the thesis's order, each with a numbered caption that says what it
        shows and what the thesis states beside it (:mod:`neuroimagery.core.thesis`); map panels carry
        no error bars."""
        from ..core.thesis import figure_caption, figure_order, is_map_panel

        paths = sorted((Path(p) for p in paths), key=lambda p: figure_order(p.stem))
        for i, p in enumerate(paths, 1):
            self.figure(p, figure_caption(p.stem, i, "" if is_map_panel(p.stem) else errorbars), root=run_root)
        return self

    def figure(self, path: str | Path, caption: str, root: str | Path | None = None) -> "Report":
        rel = Path(path).relative_to(root) if root is not None else Path(path)
        alt = caption.split(". ")[0] if caption.startswith("Figure ") else caption
        self.lines += [f"![{alt}]({rel.as_posix()})", "", f"*{caption}*", ""]
        return self

    def text(self) -> str:
        return "\n".join(self.lines).rstrip() + "\n"

    def write(self, path: str | Path) -> Path:
        return write_text(path, self.text())


def reproducibility_note(seed: int) -> str:
    return (f"Seed {seed}. With the same seed and configuration every file of this run is reproduced "
            "exactly, except measured times and memory (`runtime_s` and `peak_rss_mb` in summary.json and "
            "train.json, exp5's `cost` "
            "times and task checkpoints' `timing`, any times printed in this report) and the TensorBoard "
            "event files (which carry timestamps).")
