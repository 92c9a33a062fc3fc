"""Experiment 5's configuration: composition, validation, refused and moved keys, the studied
alternatives (conf/experiment/exp5/*.yaml)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from hydra.errors import ConfigCompositionException
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from conftest import make_cfg  # noqa: E402

from neuroimagery.experiments.exp5 import protocol as exp5, config as exp5_config  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def compose(*overrides):
    return make_cfg("experiment=exp5", *overrides)


# ---------------------------------------------------------------------------------- config
def test_config_composes_and_validates():
    from neuroimagery.config import validate

    conf = validate(compose("preset=quick"))
    e = conf.experiment
    assert e.name == "exp5" and e.brain.eta == 1e-4 and e.brain.gamma == 0.8
    assert e.sequencing.attempts == 5 and e.acquisition.n_dmps == 10 and e.world.environment == "robot"
    assert exp5.repetitions(conf) == e.quick.repetitions == 3
    assert len(exp5.groups(e)) == 11


@pytest.mark.parametrize("key,value", [("sequencing.attempts", 0), ("brain.gamma", 1.5),
                                       ("hp1_ages", [14]), ("situations", ["near"]), ("sequencing.temperature", 0.0),
                                       ("acquisition.explore_patience", 0), ("world.table_contact", "sideways"),
                                       ("acquisition.n_dmps", 5),
                                       ("world.environment", "pybullet"), ("engine.n_jobs", 0), ("quick.repetitions", 0)])
def test_config_rejects_bad_values_naming_the_key(key, value):
    import re

    group, _, k = key.rpartition(".")
    with pytest.raises(ValueError, match=re.escape(f"experiment.{key}") + r"(\[\d+\])? "):  # a list item by index
        if group:
            {"quick": exp5_config.QuickParams, **exp5_config.GROUPS}[group](**{k: value})
        else:
            exp5.Exp5Config(**{key: value})


def test_a_key_of_the_flat_layout_of_0x_is_refused_in_one_line_naming_the_version(tmp_path):
    from dataclasses import asdict

    import neuroimagery

    now = exp5_config.dotted(asdict(exp5.Exp5Config()))
    assert len([k for k in now if "." not in k]) == 9  # the protocol's keys stay at the top
    # on the command line: one error line, the closest key and the version, before any work
    p = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "experiment=exp5", "experiment.c3_eta=0.2",
                        f"hydra.run.dir={tmp_path / 'r'}"], capture_output=True, text=True, cwd=ROOT, timeout=120)
    lines = [ln for ln in (p.stdout + p.stderr).splitlines() if ln.strip() and not ln.startswith("pybullet build")]
    assert p.returncode == 2 and lines == [f"error: experiment.c3_eta is not a key of exp5 in neuroimagery "
                                           f"{neuroimagery.__version__} (did you mean experiment.brain.c3_eta?); "
                                           "keys of 0.x releases: CHANGELOG.md"]
    assert not (tmp_path / "r" / "checkpoints").exists()


def test_misspelt_key_is_rejected():
    with pytest.raises(ConfigCompositionException, match="attempt"):
        compose("experiment.attempt=4")


def test_each_alternative_config_changes_one_choice_of_the_default():
    """conf/experiment/exp5/*.yaml: every studied alternative composes, validates, and differs from
    the default Experiment 5 in the one key it names."""
    from dataclasses import asdict
    from pathlib import Path

    from neuroimagery.config import validate

    base = exp5_config.dotted(asdict(validate(compose()).experiment))
    files = sorted((Path(__file__).resolve().parents[1] / "conf" / "experiment" / "exp5").glob("*.yaml"))
    assert [f.stem for f in files] == ["table_grip", "table_yield"]
    for f in files:
        alt = exp5_config.dotted(asdict(validate(make_cfg(f"experiment=exp5/{f.stem}")).experiment))
        changed = [k for k in base if alt[k] != base[k]]
        assert len(changed) == 1, (f.name, changed)


def test_a_key_that_went_in_0x_is_refused():
    from neuroimagery.config import unknown_key_message

    hint = unknown_key_message("Could not override 'experiment.retrieve_x'; Key 'retrieve_x' not in 'Exp5Config'\n"
                               "    full_key: experiment.retrieve_x")
    assert hint.startswith("experiment.retrieve_x is not a key of exp5 in neuroimagery ")
    assert hint.endswith("; keys of 0.x releases: CHANGELOG.md")
    with pytest.raises(ConfigCompositionException, match="retrieve_x"):
        compose("experiment.retrieve_x=0.4")
