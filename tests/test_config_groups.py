"""The configuration's shared groups, the refusal of keys it does not have and the declared range checks."""
import re
from pathlib import Path

import pytest

from neuroimagery.config import experiment, schema_keys, unknown_key_message
from neuroimagery.config import experiment as experiment_protocol
from neuroimagery.models.params import LcaParams, PpcParams, SelectionParams

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("group,cls,experiments", [("selection", SelectionParams, ("exp3", "exp4", "exp6")),
                                                   ("lca", LcaParams, ("exp4", "exp6")),
                                                   ("ppc", PpcParams, ("exp4", "exp6"))])
def test_experiments_that_share_a_meaning_share_the_group(group, cls, experiments):
    for name in experiments:
        value = getattr(experiment(name).config(), group)
        assert isinstance(value, cls), (name, group)


@pytest.mark.parametrize("old,new,experiment", [("experiment.lca_k", "experiment.lca.k", "exp4"),
                                                ("experiment.field_tau", "experiment.field.tau", "exp1"),
                                                ("experiment.c3_eta", "experiment.brain.c3_eta", "exp5")])
def test_a_key_of_a_0x_release_is_refused_naming_the_version_and_the_closest_key(old, new, experiment):
    import neuroimagery

    text = f"Could not override '{old}'; Key '{old.split('.')[1]}' not in '{experiment_protocol(experiment).config.__name__}'"
    line = unknown_key_message(text + f"\n    full_key: {old}")
    assert line == (f"{old} is not a key of {experiment} in neuroimagery {neuroimagery.__version__} "
                    f"(did you mean {new}?); keys of 0.x releases: CHANGELOG.md")
    assert old not in schema_keys(experiment)


@pytest.mark.parametrize("make,key", [
    (lambda: SelectionParams(tau=0.0), "experiment.selection.tau"),
    (lambda: LcaParams(dt=2.0), "experiment.lca.dt"),
    (lambda: experiment("exp6").config(step_deg=70.0), "experiment.step_deg"),
    (lambda: experiment("exp5").config(hp1_ages=[14]), "experiment.hp1_ages"),
])
def test_a_declared_check_refuses_naming_the_key(make, key):
    with pytest.raises(ValueError, match=re.escape(key)):
        make()


def test_no_hand_written_range_check_is_left():
    pattern = re.compile(r'raise ValueError\(f?"experiment\.')
    hits = [f"{p.relative_to(ROOT)}:{i}" for p in (ROOT / "neuroimagery").rglob("*.py")
            for i, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line)]
    assert hits == []
