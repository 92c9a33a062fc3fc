"""Contract 6.1 (docs/contracts.md): the completion map fills in hidden cubes of held-out chains."""
from support_exp6 import trained

from neuroimagery.experiments.exp6 import stages as exp6_stages


def test_completed_map_matches_the_whole_volume_of_held_out_chains():
    cfg, model, scene = trained()
    out = exp6_stages.completion(model, cfg, scene, count=20)
    print(out)
    assert min(out["cosine"]) >= 0.85, out
