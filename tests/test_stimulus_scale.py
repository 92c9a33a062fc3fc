"""The drawn size of the stimuli (docs/contracts.md, "Stimulus scale of Experiments 3 and 4").

The objects of Experiments 3 and 4 are drawn at the largest scale, in steps of 0.005 of the image
side, at which every unit of their edge maps, at every angle, is a unit that the forward models'
three-dot training images activate. The other sets keep the fit to the 32x32 map.
"""
from __future__ import annotations

import pytest
import torch

from neuroimagery.models.params import ForwardModelParams
from neuroimagery.vision import StimuliConfig, VisionConfig, get_stimulus_set, make_eye, resolve_stimulus_set
from neuroimagery.vision.edges import three_dot_images
from neuroimagery.vision.shapes import CH6_RADIUS_FRACTION, RADIUS_FRACTION

SIZE = 32
DEFAULT_SETS = ["exp3-a", "exp3-b", "exp3-c", "exp4-A", "exp4-B", "exp4-C"]
OTHER_CH6_SETS = ["exp4-B-long", "exp3-b-v1", "exp3-c-v1", "exp4-A-v1", "exp4-B-v1", "exp4-C-v1"]


@pytest.fixture(scope="module")
def trained_units():
    """Units that the protocol's three-dot images (default square) ever activate."""
    g = torch.Generator().manual_seed(0)
    dots = three_dot_images(20000, g, SIZE, ForwardModelParams().dot_inner)
    return dots.sum(0) > 0


@pytest.fixture(scope="module")
def eye():
    return make_eye(VisionConfig())


def _off_share(eye, sset, units, step_deg, radius_fraction=None):
    """Largest share of a map's active units that lie off ``units``, over every object,
    appearance and angle in ``step_deg`` steps."""
    if radius_fraction is not None:
        sset = sset.with_protocol(sset.angles, sset.appearances, sset.protocol, sset.rotated_side, radius_fraction)
    items = [(o, float(a), ap) for o in sset.objects for a in range(0, 360, step_deg) for ap in sset.appearances]
    maps = eye.edge_maps(sset, items, SIZE)
    assert float(maps.sum((1, 2)).min()) > 0
    return float(((maps * (~units)).sum((1, 2)) / maps.sum((1, 2))).max())


def test_sets_know_their_scale(tmp_path):
    for name in DEFAULT_SETS + OTHER_CH6_SETS:
        assert get_stimulus_set(name).radius_fraction == CH6_RADIUS_FRACTION
    assert get_stimulus_set("L").radius_fraction == RADIUS_FRACTION
    assert CH6_RADIUS_FRACTION < RADIUS_FRACTION
    # a set redrawn under another protocol keeps its size unless told otherwise
    s = get_stimulus_set("exp4-A")
    assert s.with_protocol(s.angles, s.appearances).radius_fraction == CH6_RADIUS_FRACTION
    assert s.with_protocol(s.angles, s.appearances, radius_fraction=0.3).radius_fraction == 0.3
    with pytest.raises(ValueError, match="radius_fraction"):
        s.with_protocol(s.angles, s.appearances, radius_fraction=0.6)


def test_a_user_folder_takes_the_size_of_the_set_it_replaces(tmp_path):
    import cv2
    import numpy as np

    img = np.full((64, 64, 3), 230, np.uint8)
    img[10:54, 20:30] = (40, 40, 210)
    img[10:20, 20:44] = (40, 40, 210)
    cv2.imwrite(str(tmp_path / "f.png"), img)
    folder = StimuliConfig(kind="folder", path=str(tmp_path))
    assert resolve_stimulus_set(folder, "exp3-a").radius_fraction == CH6_RADIUS_FRACTION
    assert resolve_stimulus_set(folder, "L").radius_fraction == RADIUS_FRACTION


def test_drawn_size_follows_the_scale():
    s = get_stimulus_set("exp4-A")
    big = s.with_protocol(s.angles, s.appearances, radius_fraction=RADIUS_FRACTION)
    a, b = float(s.coverage("A1", 0.0).sum()), float(big.coverage("A1", 0.0).sum())
    assert a / b == pytest.approx((CH6_RADIUS_FRACTION / RADIUS_FRACTION) ** 2, rel=0.03)


@pytest.mark.parametrize("name", DEFAULT_SETS)
def test_every_rotation_stays_on_the_trained_units(name, eye, trained_units):
    assert _off_share(eye, get_stimulus_set(name), trained_units, 5) == 0.0


def test_the_scale_is_the_largest_that_does(eye, trained_units):
    # the bars with a clear axis reach farthest; the square-like sets c and C stay inside longer
    worst = max(_off_share(eye, get_stimulus_set(n), trained_units, 5, CH6_RADIUS_FRACTION + 0.005)
                for n in ("exp3-a", "exp3-b", "exp4-A", "exp4-B"))
    assert worst > 0.0


@pytest.mark.slow
@pytest.mark.parametrize("name", DEFAULT_SETS + OTHER_CH6_SETS)
def test_every_rotation_in_1_degree_steps_stays_on_the_trained_units(name, eye, trained_units):
    assert _off_share(eye, get_stimulus_set(name), trained_units, 1) == 0.0
