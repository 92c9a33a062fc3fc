"""The one table of every setting that moved or went: ``MOVED[experiment][old key] = new key``
(both under ``experiment.``), or ``"removed; <why>"`` for a key that is no longer a setting; and
the table of settings added after runs had been stored: ``ADDED[experiment][key] = value``, the
value under which a run stored before the key existed computed what it did.

A run that sets an old key is refused with its new place (:func:`neuroimagery.config.moved_message`);
a checkpoint or a stored task file whose settings use the old names reads them under the new ones,
and one that lacks a key of ``ADDED`` reads it with its value there (:func:`rename`). Shared groups
(:mod:`neuroimagery.models.params`) move alike in every experiment that has them, so their entries
are written once here.
"""
from __future__ import annotations

import copy
import math
from typing import Collection, Mapping

REMOVED = "removed; "  # a value that starts so says why the key went, instead of naming its new place


def _group(group: str, prefix: str, names: str) -> dict[str, str]:
    return {f"{prefix}{n}": f"{group}.{n}" for n in names.split()}


# --- groups shared by several experiments
_FIELD = _group("field", "field_", "tau h a_exc sigma_exc a_inh threshold gain max_cycles")  # Exp 1-2
_SOM = _group("som", "som_", "iterations eta eta_final sigma sigma_final method threads")  # Exp 1-2
_CH6 = {"eta_fm": "fm.eta", "fm_images": "fm.images", "fm_batch": "fm.batch", "dot_inner": "fm.dot_inner",  # Exp 3-4
        "eta_posture": "posture.eta", "eta_posture_final": "posture.eta_final", "posture_sigma": "posture.sigma",
        "posture_iterations": "posture.iterations", "quick_objects": "quick.objects", "quick_fm_images": "quick.fm_images"}
_SELECTION = {"softmax_tau": "selection.tau", "max_steps": "selection.max_steps"}  # Exp 3, 4, 6
_LCA = _group("lca", "lca_", "k w threshold dt cycles input_gain")  # Exp 4, 6
_PPC = {"ppc_sigma": "ppc.sigma", "proprio_gain": "ppc.proprio_gain"}  # Exp 4, 6
_EXP6_GONE = "removed; the rebuilt Experiment 6 (search, transform, confirm) has no such part: see docs/exp6.md"

MOVED: dict[str, dict[str, str]] = {
    "exp1": {**_FIELD, **_SOM, "som_filter_sigma": "som.cluster_sigma"},
    "exp2": {**_FIELD, **_SOM, "som_cutoff": "som.cutoff", "cluster_sigma": "som.cluster_sigma",
             "quick_som_iterations": "quick.som_iterations"},
    "exp3": {**_CH6, **_SELECTION, "fm_threshold": "fm.threshold", "posture_angles": "posture.angles",
             "posture_code_sigma": "posture.code_sigma"},
    "exp4": {**_CH6, **_SELECTION, **_LCA, **_PPC, "posture_tau": "posture.tau", "lca_gain_rule": "lca.gain_rule",
             "ppc_angles": "ppc.angles", "proprio_stage": "ppc.proprio_stage", "noise_amplitude": "ppc.noise_amplitude"},
    "exp5": {  # every key of the earlier flat layout into its group, and the keys that are gone
        "quick_repetitions": "quick.repetitions",
        **_group("world", "", "environment duration_s explore_weight_sigma search_goal_sigma search_weight_sigma "
                              "toy_turn max_substep_travel explore_goals"),
        **_group("acquisition", "", "n_dmps pibb_samples pibb_temperature pibb_decay pibb_flat max_epochs "
                                    "competence_tolerance c1_repeats c2_repeats c3_repeats hip_threshold explore_batch "
                                    "explore_max_rollouts explore_patience spare_dmps"),
        **_group("brain", "", "c1_eta c2_eta c3_eta c3_sigma c3_action_gain c3_recall c3_outcomes q_form eta gamma"),
        **_group("sequencing", "", "attempts temperature test_temperature planning_test active_threshold"),
        **_group("engine", "", "n_jobs share_library_across_situations filmstrip_repetition reuse_libraries"),
        "retrieve_x": "removed; the reachable area is the free left hand's reach, from its kinematics (docs/robot.md)",
        "posture_4": "removed; the four postures are fitted to the scene criteria of docs/robot.md",
        "reach_bound": "removed; a movement is bounded by the joint limits only (docs/robot.md)",
        "goal_frame": "removed; DMP goals are joint angles (docs/exp5.md)",
        "explore_goal_sigma": "removed; goal noise is 1/10 of each joint's range (WorldConfig.goal_noise_share)",
    },
    "exp6": {"eta_fm": "fm.eta", "fm_images": "fm.images", "fm_batch": "fm.batch", "fm_memory_mb": "fm.memory_mb",
             "quick_objects": "quick.objects", "quick_fm_images": "quick.fm_images", **_SELECTION, **_LCA, **_PPC,
             **{k: _EXP6_GONE for k in ("hidden", "posture_angles", "eta_posture", "posture_sigma", "posture_iterations",
                                        "posture_readout", "unreachable", "match_radius")}},
}


# settings added after runs had been stored (keys without the ``experiment.`` prefix): the value that
# reproduces what a run stored without the key computed; a stored run that lacks one reads it so
ADDED: dict[str, dict[str, object]] = {
    "exp5": {
        # added while the layout was flat (a task file of that layout lacks them)
        "acquisition.spare_dmps": "none", "brain.c3_outcomes": "success", "acquisition.pibb_flat": "average",
        "world.toy_turn": "reset",
        # the table rule: earlier runs lifted the rake vertically; the grip's bound plays no part then
        "world.table_contact": "lift", "world.grip_pivot_max": math.radians(10.0),
    },
    "exp6": {"search.starts": [], "search.keep": 8},  # earlier runs refined the matched-axes candidates only
}


def moved(experiment: str) -> dict[str, str]:
    """``{old key: new key}`` of ``experiment`` (without the ``experiment.`` prefix), the keys
    that went left out."""
    return {k: v for k, v in MOVED.get(experiment, {}).items() if not v.startswith(REMOVED)}


def rename(settings: Mapping[str, object], experiment: str, prefix: str = "experiment.",
           within: Collection[str] | None = None) -> dict[str, object]:
    """``settings`` (dotted keys, e.g. a checkpoint's stored training settings) with every old key
    of ``experiment`` under its new name (a key already under its new name wins), and every key of
    ``ADDED`` they lack with its value there (only those in ``within``, when given: the settings
    they are compared with)."""
    table = {f"{prefix}{k}": f"{prefix}{v}" for k, v in moved(experiment).items()}
    out = {k: v for k, v in settings.items() if k not in table}
    for k, v in settings.items():
        if k in table:
            out.setdefault(table[k], v)
    for k, v in ADDED.get(experiment, {}).items():
        if within is None or f"{prefix}{k}" in within:
            out.setdefault(f"{prefix}{k}", copy.deepcopy(v))
    return out


def fill_added(config: dict, experiment: str) -> dict:
    """A copy of the nested settings ``config`` (groups as dicts, no prefix) with every key of
    ``ADDED`` it lacks set to its value there."""
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in config.items()}
    for key, v in ADDED.get(experiment, {}).items():
        *groups, name = key.split(".")
        node = out
        for g in groups:
            node = node.setdefault(g, {})
        node.setdefault(name, copy.deepcopy(v))
    return out
