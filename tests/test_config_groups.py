"""The configuration's shared groups, the one table of moved keys and the declared range checks."""
import re
from pathlib import Path

import pytest

from neuroimagery.config import experiment, moved_keys, moved_message, schema_keys
from neuroimagery.models.params import LcaParams, PpcParams, SelectionParams
from neuroimagery.moved_keys import ADDED, MOVED, REMOVED, rename

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("group,cls,experiments", [("selection", SelectionParams, ("exp3", "exp4", "exp6")),
                                                   ("lca", LcaParams, ("exp4", "exp6")),
                                                   ("ppc", PpcParams, ("exp4", "exp6"))])
def test_experiments_that_share_a_meaning_share_the_group(group, cls, experiments):
    for name in experiments:
        value = getattr(experiment(name).config(), group)
        assert isinstance(value, cls), (name, group)


@pytest.mark.parametrize("name", sorted(MOVED))
def test_every_moved_key_points_at_a_key_of_the_schema_and_is_no_key_itself(name):
    keys = set(schema_keys(name))
    for old, new in moved_keys(name).items():
        assert old not in keys, old
        if not new.startswith(REMOVED):
            assert new in keys, (old, new)
            assert new in moved_message(old, name)


def test_old_flat_keys_of_exp4_and_exp6_name_their_group():
    assert "experiment.lca.k" in moved_message("experiment.lca_k", "exp4")
    assert "experiment.ppc.angles" in moved_message("experiment.ppc_angles", "exp4")
    assert "experiment.selection.tau" in moved_message("experiment.softmax_tau", "exp6")
    assert "experiment.ppc.sigma" in moved_message("experiment.ppc_sigma", "exp6")
    assert "experiment.selection.max_steps" in moved_message("experiment.max_steps", "exp3")
    assert moved_message("experiment.selection.max_steps", "exp4") is None


def test_settings_stored_under_old_names_read_under_the_new():
    stored = {"experiment.lca_k": 0.5, "experiment.map_size": 32, "seed": 0}
    assert rename(stored, "exp4") == {"experiment.lca.k": 0.5, "experiment.map_size": 32, "seed": 0}


@pytest.mark.parametrize("name", sorted(ADDED))
def test_every_added_key_is_a_key_of_the_schema_with_a_value_it_accepts(name):
    keys = set(schema_keys(name))
    module = experiment(name)
    for key, value in ADDED[name].items():
        assert f"experiment.{key}" in keys, key
        group, field = key.split(".")
        cls = type(getattr(module.config(), group))
        assert getattr(cls(**{field: value}), field) == value  # a value the setting accepts


def test_settings_stored_before_a_key_existed_read_it_with_its_earlier_value():
    stored = {"experiment.search.refine": [10.0], "seed": 0}
    now = rename(stored, "exp6")
    assert now["experiment.search.starts"] == [] and now["experiment.search.keep"] == 8
    assert now["experiment.search.refine"] == [10.0]  # a stored value is kept
    assert rename({"experiment.search.keep": 4}, "exp6")["experiment.search.keep"] == 4
    # only the keys the settings are compared with
    assert rename(stored, "exp6", within={"experiment.search.keep"}) == {**stored, "experiment.search.keep": 8}
    assert rename({}, "exp5")["experiment.world.table_contact"] == "lift"


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
