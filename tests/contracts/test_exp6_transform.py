"""Contract 6.2 (docs/contracts.md): nine chained forward-model steps stay close to one turn, and a
same image still beats a mirror image after them."""
from support_exp6 import trained

from neuroimagery.experiments import exp6_stages


def test_chained_steps_match_one_turn_and_keep_same_above_mirror():
    cfg, model, scene = trained()
    out = exp6_stages.transform(model, cfg, scene, count=10)
    print(out)
    assert out["steps"] == 9
    assert min(out["cosine"].values()) >= 0.8, out
    assert out["same_above_mirror"] >= 0.9, out
