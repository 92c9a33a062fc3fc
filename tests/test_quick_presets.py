"""The quick presets meet the rule of docs/choices.md ("Quick presets") over seeds 0-4: every effect
that holds in the full run keeps its sign, every headline rate lies within 15 points of the full
run's, and the quick run takes at most the larger of a quarter of the full run's CPU time and 30 s.
Slow (two runs per seed and experiment); the experiments whose presets were sized by the rule."""
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("quick_presets", ROOT / "benchmarks" / "quick_presets.py")
qp = importlib.util.module_from_spec(spec)
spec.loader.exec_module(qp)


@pytest.mark.slow
@pytest.mark.parametrize("experiment", ["exp1", "exp2"])
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_quick_preset_keeps_the_full_runs_effects_and_rates(tmp_path, experiment, seed):
    full = qp.run(experiment, seed, tmp_path / "full", [])
    quick = qp.run(experiment, seed, tmp_path / "quick", ["preset=quick"])
    assert qp.admissible(full, quick) == []
    assert quick["cpu_s"] <= max(full["cpu_s"] / 4, 30.0)
