"""Contract 6.2 (docs/contracts.md): nine chained forward-model steps stay close to one turn, and a
same image still beats a mirror image after them."""
import pytest
from support_exp6 import aligned, assert_every_set_and_kind, trained

from neuroimagery.experiments.exp6 import stages as exp6_stages


def test_chained_steps_match_one_turn_and_keep_same_above_mirror():
    cfg, model, scene = trained()
    out = exp6_stages.transform(model, cfg, scene, count=10)
    print(out)
    assert out["steps"] == 9
    assert min(out["cosine"].values()) >= 0.8, out
    assert out["same_above_mirror"] >= 0.9, out


@pytest.mark.xfail(strict=True, reason="contract 6.2c is not met in depth: 0.83 of the training objects' and 0.88 of "
                   "held-out chains' depth pairs end within half a step of the estimate (picture plane 1.00 / 0.95; seed 0); "
                   "every miss is an estimate more than half a step from the truth, off the steps' lattice")
def test_steps_carry_out_the_search_estimate():
    """Contract 6.2c: the net turn composed from the steps' efference copies ends within half a step
    of the search's estimate, same pairs of the training objects and of held-out chains."""
    cfg, model, scene = trained()
    assert_every_set_and_kind(exp6_stages.realisation(model, cfg, scene, al=aligned()), 0.9)
