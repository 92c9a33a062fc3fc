"""Contract 6.4 (docs/contracts.md): after the transform, the largest mismatch cluster separates
mirrors from same objects with a cut fixed on the training objects."""
import pytest
from support_exp6 import aligned, trained

from neuroimagery.experiments.exp6 import stages as exp6_stages


@pytest.mark.xfail(strict=True, reason="contract 6.4 is not met on held-out chains: the cut puts 0.925 of the "
                   "training pairs but 0.78 of held-out chains' pairs on their side (seed 0); their depth views, completed "
                   "from one seen face, leave same pairs over the cut and mirrors under it (docs/contracts.md, 6.4: where "
                   "the misses arise)")
def test_mismatch_cluster_separates_training_and_held_out_pairs():
    cfg, model, scene = trained()
    out = exp6_stages.confirm(model, cfg, scene, al=aligned())
    print(out)
    assert out["train"] >= 0.9, out
    assert out["held_out"] >= 0.9, out
