"""The thesis's target numbers and the figures it draws, each with where the thesis states it.

One module for reports, figures, tests and docs alike. ``value`` is what the thesis's text states
(a rate as a fraction, an RT in the experiment's unit); where the text gives only a trend, the entry
says so in ``states`` and has no value. Each entry keeps the line of the statement in the plain
text of the thesis the project was built from (a pointer for maintainers: ``SPEC.md`` maps those
lines); what users see is the section it lies in (:func:`section_of`) and the figure, table or
equation number, which any copy of the thesis has.
"""
from __future__ import annotations

from dataclasses import dataclass


# the first line of each heading of chapters 5-8 in the thesis text: section_of() maps a line to
# the section it lies in
SECTIONS = ((574, "5"), (580, "5.1"), (590, "5.1.1"), (673, "5.1.2"), (714, "5.1.3"), (726, "5.2"),
            (730, "5.2.1"), (843, "5.2.2"), (887, "5.2.3"), (899, "6"), (909, "6.1"), (917, "6.1.1"),
            (1035, "6.1.2"), (1059, "6.1.3"), (1069, "6.2"), (1083, "6.2.1"), (1236, "6.2.3"), (1322, "7"),
            (1328, "7.1"), (1330, "7.1.1"), (1352, "7.1.2"), (1676, "7.1.3"), (1708, "7.1.4"), (1726, "8"))


def section_of(line: int) -> str:
    """``'section 6.2.3'``: the section of the thesis a line of its text lies in (chapters 5-8)."""
    if line < SECTIONS[0][0]:
        raise ValueError(f"line {line} lies before chapter 5")
    return "section " + [name for start, name in SECTIONS if start <= line][-1]


@dataclass(frozen=True)
class Target:
    """One number the thesis states: ``value`` (a fraction for rates), ``line`` of the text
    (:func:`section_of` gives its section)."""

    value: float
    line: int
    what: str


@dataclass(frozen=True)
class Figure:
    """A thesis figure redrawn from a run: its label, what it plots, what the thesis's text states
    about it (values or only a trend) and the line of that statement (:func:`section_of` gives
    its section, which captions cite)."""

    label: str
    shows: str
    states: str
    line: int


# Experiment 1 (section 5.1.2): rotation success per object and test
EXP1 = {
    "recognition/A rotation success": Target(51 / 52, 697, "object A rotated correctly, recognition (51 of 52)"),
    "recognition/B rotation success": Target(1.0, 697, "object B rotated correctly, recognition"),
    "generalisation/A rotation success": Target(93 / 96, 697, "object A rotated correctly, unseen orientations (93 of 96)"),
    "generalisation/B rotation success": Target(92 / 96, 697, "object B rotated correctly, unseen orientations (92 of 96)"),
    "overall rotation success": Target(0.966, 697, "rotation success over both tests"),
}

# Experiment 2 (section 5.2.2)
EXP2 = {
    "rotation success": Target(192 / 196, 857, "left stimulus rotated to the target (192 of 196)"),
    "correct answers": Target(168 / 196, 857, "correct same/mirror answers (168 of 196)"),
}

# Experiment 3 (section 6.1.2): error rates of Fig. 6.5b; Gen-II's step at 0 deg (Fig. 6.5a)
EXP3 = {
    "recog/none error rate": Target(0.187, 1043, "error rate, Recog"),
    "gen1/none error rate": Target(0.247, 1043, "error rate, Gen-I"),
    "gen2/none error rate": Target(0.543, 1043, "error rate, Gen-II"),
    "gen2/none steps at 0 deg": Target(1.0, 1040, "rotation steps of Gen-II at zero disparity (about one)"),
}

# Experiment 4 (section 6.2.3): correct rates of Fig. 6.9c; RT per rotation step (Fig. 6.9a, as the text reads it)
EXP4 = {
    "recog/none correct rate": Target(0.79, 1248, "correct responses, Recog (about 79 %)"),
    "gen1/none correct rate": Target(0.86, 1248, "correct responses, Gen1 (about 86 %)"),
    "gen2/none correct rate": Target(0.59, 1248, "correct responses, Gen2 (about 59 %)"),
    "cycles per rotation step": Target(10.0, 1267, "RT at n required steps slightly above 10 n cycles"),
}

TREND = "the thesis states only a trend here"

FIGURES = {
    # Experiment 1
    "fig5_4a_success": Figure("Fig. 5.4a", "map activity of a sample trial that rotates, one row per cycle",
                              "a sample trial; no values", 684),
    "fig5_4b_failure": Figure("Fig. 5.4b", "map activity of a sample trial that fails to rotate, one row per cycle",
                              "a sample failure (object A at -90 deg in the recognition test)", 684),
    "fig5_5a_rt": Figure("Fig. 5.5a", "mean RT against the rotated object's orientation, per object",
                         f"RT rises with |disparity|, an inverse V; {TREND}", 697),
    "fig5_5b_rt": Figure("Fig. 5.5b", "object A: mean RT of seen against unseen orientations",
                         f"some unseen orientations take longer than seen ones of larger disparity; {TREND}", 699),
    # Experiment 2
    "fig5_7a_success": Figure("Fig. 5.7a", "map activity of a sample trial that rotates, one row per cycle",
                              "a sample trial; no values", 876),
    "fig5_7b_failure": Figure("Fig. 5.7b", "map activity of a sample trial that fails to rotate, one row per cycle",
                              "a sample failure; no values", 876),
    "fig5_8a_rt": Figure("Fig. 5.8a", "mean RT against disparity per pair of object types (AA, AB, BA, BB)",
                         f"RT rises with disparity, no effect of the object types; {TREND}", 859),
    "fig5_8b_rt": Figure("Fig. 5.8b", "mean RT against disparity with no, matching and mismatching proprioception",
                         f"mismatch slows RT, accuracy unchanged; {TREND}", 869),
    # Experiment 3
    "fig6_5a_rt": Figure("Fig. 6.5a", "mean RT (rotation steps) against disparity per test",
                         "RT rises with disparity for Recog and Gen-I; Gen-II lower, flat past 90 deg, about one "
                         "step at 0 deg (dashed)", 1040),
    "fig6_5b_error": Figure("Fig. 6.5b", "error rate per test",
                            "18.7 % (Recog), 24.7 % (Gen-I), 54.3 % (Gen-II) (dashed)", 1043),
    "fig6_5c_error": Figure("Fig. 6.5c", "error rate against disparity per test",
                            f"Recog and Gen-I drop at 135 deg; Gen-II rises from 45 deg; {TREND}", 1043),
    # Experiment 4
    "fig6_9a_rt": Figure("Fig. 6.9a", "mean RT (accumulator cycles) against disparity per test",
                         f"RT rises with disparity for every test; {TREND}", 1246),
    "fig6_9b_error": Figure("Fig. 6.9b", "error rate against disparity per test",
                            f"error rate rises with disparity, Gen2 highest; {TREND}", 1248),
    "fig6_9c_correct": Figure("Fig. 6.9c", "correct responses per test",
                              "about 79 % (Recog), 86 % (Gen1), 59 % (Gen2) (dashed)", 1248),
    "fig6_9d_steps": Figure("Fig. 6.9a (text)", "mean RT against the rotation steps the disparity requires",
                            "slightly above 10 n cycles for n steps (dashed: 10 n)", 1267),
    "fig6_10a_rt": Figure("Fig. 6.10a", "Recog: mean RT against disparity by proprioception condition",
                          f"incongruent lengthens RT; with noise, congruent shortens it; {TREND}", 1267),
    "fig6_10b_error": Figure("Fig. 6.10b", "Recog: error rate against disparity by proprioception condition",
                             f"incongruent raises errors at high disparity; {TREND}", 1267),
    "fig6_10c_correct": Figure("Fig. 6.10c", "Recog: correct responses by proprioception condition",
                               f"incongruent lowers the correct rate, congruent gains little without noise; {TREND}",
                               1267),
    "fig6_11a_rt": Figure("Fig. 6.11a", "Gen1: mean RT against disparity by proprioception condition",
                          f"congruent improves, incongruent impairs RT at high disparity; {TREND}", 1278),
    "fig6_11b_error": Figure("Fig. 6.11b", "Gen1: error rate against disparity by proprioception condition",
                             f"the effects are more pronounced in error rate; {TREND}", 1278),
    "fig6_11c_correct": Figure("Fig. 6.11c", "Gen1: correct responses by proprioception condition",
                               f"the effects are more pronounced in correct rate; {TREND}", 1278),
    "fig6_12a_recog": Figure("Fig. 6.12", "Recog: sample trials at a large disparity, one row per rotation step",
                             "map activity step by step; no values", 1296),
    "fig6_12b_gen1": Figure("Fig. 6.12", "Gen1: sample trials at a large disparity, one row per rotation step",
                            "map activity step by step; no values", 1296),
    "fig6_12c_gen2": Figure("Fig. 6.12", "Gen2: sample trials at a large disparity, one row per rotation step",
                            "map activity step by step; no values", 1296),
    "fig6_13a_match": Figure("Fig. 6.13", "congruent proprioception: sample trials, one row per rotation step",
                             "map activity step by step; no values", 1318),
    "fig6_13b_mismatch": Figure("Fig. 6.13", "incongruent proprioception: sample trials, one row per rotation step",
                                "map activity step by step; no values", 1318),
}


# the same figures drawn for a user's stimuli (test ``custom``)
for _k in ("a_rt", "b_error", "c_correct"):
    _f = FIGURES[f"fig6_10{_k}"]
    FIGURES[f"fig6_10_custom{_k}"] = Figure(_f.label, _f.shows.replace("Recog", "your stimuli"), _f.states, _f.line)
FIGURES["fig6_12_custom"] = Figure("Fig. 6.12", "your stimuli: sample trials at a large disparity, one row per "
                                   "rotation step", "map activity step by step; no values", 1296)
MAP_PANELS = ("fig5_4a_success", "fig5_4b_failure", "fig5_7a_success", "fig5_7b_failure", "fig6_12a_recog",
              "fig6_12b_gen1", "fig6_12c_gen2", "fig6_13a_match", "fig6_13b_mismatch", "fig6_12_custom")


def is_map_panel(stem: str) -> bool:
    """Whether a figure file shows map activity (no error bars) rather than a plot of means."""
    return stem in MAP_PANELS or stem.startswith("maps_")


def figure_order(stem: str) -> tuple:
    """Sort key that puts figure files in the thesis's order (5.4 < 5.5 < 6.9 < 6.10 ...)."""
    import re

    parts = re.findall(r"\d+|[a-z]+", stem.lower())
    return tuple((0, int(p), "") if p.isdigit() else (1, 0, p) for p in parts)


def figure_caption(stem: str, number: int, errorbars: str = "") -> str:
    """``Figure n. (Fig. x.y) what it shows. Thesis: what it states (section).`` for a figure file
    ``stem``; a stem the thesis has no entry for (a user's stimuli, say) gets its own words."""
    f = FIGURES.get(stem)
    if f is None and stem.startswith("maps_"):
        key = stem.removeprefix("maps_").replace("_", "/", 1)
        return (f"Figure {number}. {key}: sample trials, one row per rotation step, chosen among the trials that "
                "rotated and decided, largest disparity first (the panel's title says how). The thesis has no such "
                "figure for this experiment.")
    if f is None:
        return f"Figure {number}. {stem.replace('_', ' ')}{'. ' + errorbars if errorbars else ''}"
    eb = f" {errorbars}." if errorbars else ""
    return f"Figure {number}. ({f.label}) {f.shows[0].upper() + f.shows[1:]}.{eb} Thesis: {f.states} ({section_of(f.line)})."


# Experiment 5
# Section 7.1.3: HP1 (Fig. 7.9: tool behind about 90 % at every age, 100 % at 14 months; tool far
# about 0, 10, 40, 45, 60 % for 2..6 skills) and HP2 (Fig. 7.10: no training about 60 % behind and
# 20 % far). Keyed by hypothesis, situation and level (skills or trials).
EXP5 = {
    "hp1": {"behind": {2: 1.0, 3: 0.9, 4: 0.9, 5: 0.9, 6: 0.9}, "far": {2: 0.0, 3: 0.1, 4: 0.4, 5: 0.45, 6: 0.6}},
    "hp2": {"behind": {0: 0.6}, "far": {0: 0.2}},
}
EXP5_LINES = {"hp1/behind": 1690, "hp1/far": 1692, "hp2": 1699, "table_7_1": 1439}
# Table 7.1 (section 7.1.2): which interesting events (retrieve, touch, south, north, west, east) each
# initial posture can produce, and from which postures each skill (P, T, S, N, W, E) can be learnt
EXP5_TABLE_7_1 = {
    "posture-1": {"events": [1, 0, 1, 0, 1, 0], "skills": [1, 0, 1, 0, 1, 0]},
    "posture-2": {"events": [0, 1, 1, 0, 1, 0], "skills": [1, 1, 1, 0, 1, 0]},
    "posture-3": {"events": [0, 1, 1, 1, 1, 1], "skills": [0, 1, 1, 1, 1, 1]},
    "posture-4": {"events": [0, 1, 1, 1, 1, 1], "skills": [0, 1, 1, 1, 1, 1]},
}
