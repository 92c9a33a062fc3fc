"""Contract 6.4 (docs/contracts.md): after the transform, the largest mismatch cluster separates
mirrors from same objects with a cut fixed on the training objects."""
from support_exp6 import trained

from neuroimagery.experiments import exp6_stages


def test_mismatch_cluster_separates_training_and_held_out_pairs():
    cfg, model, scene = trained()
    out = exp6_stages.confirm(model, cfg, scene, count=6)
    assert out["train"] >= 0.9, out
    assert out["held_out"] >= 0.9, out
