"""Contract 6.3 (docs/contracts.md): the search estimates the rotation required from the two images."""
from support_exp6 import trained

from neuroimagery.experiments import exp6_stages


def test_search_finds_axis_and_angle_of_held_out_same_pairs():
    cfg, model, scene = trained()
    out = exp6_stages.search(model, cfg, scene, count=6)
    print(out)
    assert out["picture"] >= 0.95, out
    assert out["depth"] >= 0.85, out
