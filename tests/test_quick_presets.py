"""The quick presets meet the claims of the rule of docs/choices.md ("Quick presets") over seeds 0-4,
each seed's quick run against the full run of that seed: every effect that holds in the full run
keeps its direction, every headline rate lies within 15 points of the full run's, and the quick run
takes at most the larger of a quarter of the full run's CPU time and 30 s, start-up aside. Slow (two
runs per seed and experiment; Exp 6's full run takes about 6 minutes of CPU); the experiments whose
presets were sized by the rule."""
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("quick_presets", ROOT / "benchmarks" / "quick_presets.py")
qp = importlib.util.module_from_spec(spec)
spec.loader.exec_module(qp)


@pytest.mark.slow
@pytest.mark.parametrize("experiment", ["exp1", "exp2", "exp6"])
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_quick_preset_keeps_the_full_runs_effects_and_rates(tmp_path, experiment, seed):
    full = qp.run(experiment, seed, tmp_path / "full", [])
    quick = qp.run(experiment, seed, tmp_path / "quick", ["preset=quick"])
    assert quick["participants"] < full["participants"]  # a smaller protocol
    assert qp.admissible(full, quick) == []
    assert qp.over_time(full, quick) == []


def test_the_claims_are_checked_as_stated():
    """The checks themselves: a flipped effect, a rate 15.1 points off and a run over the time bound are refused."""
    eff = {"effect": "RT rises", "expected": ">0", "holds": True, "value": 0.8}
    full = {"effects": [eff], "tests": {"t": {"correct_rate": 0.9}}, "cpu_work_s": 400.0}
    assert qp.admissible(full, {"effects": [dict(eff, value=0.1)], "tests": {"t": {"correct_rate": 0.75}}}) == []
    assert qp.admissible(full, {"effects": [dict(eff, value=-0.1)], "tests": {"t": {"correct_rate": 0.9}}})
    assert qp.admissible(full, {"effects": [eff], "tests": {"t": {"correct_rate": 0.749}}})
    assert qp.over_time(full, {"cpu_work_s": 100.0}) == [] and qp.over_time(full, {"cpu_work_s": 100.1})
    assert qp.over_time({"cpu_work_s": 60.0}, {"cpu_work_s": 30.0}) == []
