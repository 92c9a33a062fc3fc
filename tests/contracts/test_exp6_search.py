"""Contract 6.3 (docs/contracts.md): the search estimates the rotation required from the two images."""
import pytest
from support_exp6 import aligned, assert_every_set_and_kind, trained

from neuroimagery.experiments.exp6 import stages as exp6_stages


def test_search_finds_axis_and_angle_of_held_out_same_pairs():
    cfg, model, scene = trained()
    out = exp6_stages.search(model, cfg, scene, count=6)
    print(out)
    assert out["picture"] >= 0.95, out
    assert out["depth"] >= 0.85, out


@pytest.mark.xfail(strict=True, reason="contract 6.3b is not met in depth: estimates within half a step in 0.80 of the "
                   "training objects' and 0.80 of held-out chains' depth pairs (picture plane 0.97 / 0.95; seed 0)")
def test_search_estimate_is_within_half_a_step_of_the_true_alignment():
    """Contract 6.3b: same pairs of the training objects and of held-out chains."""
    cfg, model, scene = trained()
    assert_every_set_and_kind(exp6_stages.precision(model, cfg, scene, al=aligned()), 0.9)
