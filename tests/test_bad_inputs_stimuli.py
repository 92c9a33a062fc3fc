"""Stimulus folders and images, refused by name before any work: files that cannot be fully
decoded (truncated, corrupt), links that lead nowhere, images too large (judged from the header,
before decoding, for a run and for ``stimuli --measure``), a shape only in the transparency."""
from __future__ import annotations

import os

import cv2
import numpy as np
import pytest
from PIL import Image

from neuroimagery.app import stimuli

from support_bad_inputs import evaluating, no_training, refused  # noqa: F401 (fixture)


def _shape(w=64, h=64):
    img = np.full((h, w, 3), 255, np.uint8)
    img[h // 4: h // 2, w // 4: 3 * w // 4] = (0, 0, 200)
    return img


def _folder(tmp_path, kind):
    """A folder with one good shape and one bad file of ``kind``; returns (folder, bad file's name)."""
    d = tmp_path / f"stim_{kind}"
    d.mkdir()
    assert cv2.imwrite(str(d / "good.png"), _shape())
    bad = d / "bad.png"
    if kind == "truncated jpeg":
        bad = d / "bad.jpg"
        assert cv2.imwrite(str(bad), _shape(256, 256))
        bad.write_bytes(bad.read_bytes()[: bad.stat().st_size // 2])
    elif kind == "truncated png":
        assert cv2.imwrite(str(bad), _shape(256, 256))
        bad.write_bytes(bad.read_bytes()[: bad.stat().st_size - 40])
    elif kind == "corrupt":
        bad.write_bytes(b"\x89PNG\r\n\x1a\n" + os.urandom(200))
    elif kind == "symlink loop":
        os.symlink("bad.png", bad)
    elif kind == "broken link":
        os.symlink("nowhere.png", bad)
    elif kind == "alpha only":
        rgba = np.zeros((64, 64, 4), np.uint8)
        rgba[16:32, 16:48, 3] = 255  # the shape is opaque black on transparent black: only alpha shows it
        Image.fromarray(rgba, "RGBA").save(bad)
    elif kind == "huge":
        Image.new("RGB", (5000, 10), (255, 255, 255)).save(bad)
    elif kind == "empty file":
        bad.write_bytes(b"")
    elif kind == "text":
        bad.write_text("not an image")
    return d, bad.name


KINDS = [("truncated jpeg", "cannot be fully decoded"), ("truncated png", "cannot be fully decoded"),
         ("corrupt", "bad.png"), ("symlink loop", "loops back on itself"), ("broken link", "leads to no file"),
         ("alpha only", "transparent"), ("huge", "5000 x 10"), ("empty file", "bad.png"), ("text", "bad.png")]


@pytest.mark.parametrize("kind,needle", KINDS, ids=[k for k, _ in KINDS])
@pytest.mark.parametrize("exp", ["exp3", "exp4"])
def test_bad_files_in_a_stimulus_folder_are_refused_by_name(tmp_path, capsys, no_training, exp, kind, needle):
    d, name = _folder(tmp_path, kind)
    refused(capsys, evaluating(tmp_path / "run", f"experiment={exp}", "stimuli=folder", f"stimuli.path={d}"), name, needle)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("kind,needle", KINDS, ids=[k for k, _ in KINDS])
def test_the_stimuli_tool_refuses_the_same_files(tmp_path, capsys, kind, needle):
    d, name = _folder(tmp_path, kind)
    refused(capsys, lambda: stimuli.main(["--measure", str(d)]), name, needle)


def test_measure_refuses_a_huge_png_from_its_header_before_decoding(tmp_path, capsys, monkeypatch):
    d = tmp_path / "big"
    d.mkdir()
    Image.new("L", (12000, 12000), 255).save(d / "a.png")  # 144 Mpixel: decoding it would take seconds

    def no_decoding(*a, **k):
        raise AssertionError("the image was decoded")

    monkeypatch.setattr(cv2, "imread", no_decoding)
    monkeypatch.setattr(Image.Image, "load", no_decoding)
    refused(capsys, lambda: stimuli.main(["--measure", str(d)]), "a.png", "12000 x 12000")


def test_a_transparent_image_whose_shape_is_in_its_colours_is_used(tmp_path):
    from neuroimagery.vision.stimulus_sets import load_folder

    d = tmp_path / "ok"
    d.mkdir()
    rgba = np.dstack([_shape()[..., ::-1], np.full((64, 64), 255, np.uint8)])
    rgba[0, 0, 3] = 0  # transparent in one corner
    Image.fromarray(rgba, "RGBA").save(d / "a.png")
    assert len(load_folder(d).objects) == 1


# ------------------------------------------------------ folders: missing, empty, too few shapes
def _png(path, image):
    assert cv2.imwrite(str(path), image)


def _shape_image(w=64, h=64):
    img = np.full((h, w, 3), 255, np.uint8)
    img[h // 4: h // 2, w // 4: 3 * w // 4] = (0, 0, 200)
    return img


def _whole_folder(tmp_path, kind):
    d = tmp_path / f"stim_{kind}"
    d.mkdir()
    if kind == "corrupt":
        (d / "a.png").write_bytes(os.urandom(300))
    elif kind == "blank":
        _png(d / "a.png", np.full((64, 64, 3), 255, np.uint8))
    elif kind == "huge":
        _png(d / "a.png", _shape_image(4097, 8))
    elif kind == "one":
        _png(d / "a.png", _shape_image())
    elif kind == "file":
        d.rmdir()
        d.write_text("not a folder")
    return d


@pytest.mark.parametrize("exp,kind,needle", [
    ("exp4", "empty", "no PNG or JPEG"), ("exp3", "corrupt", "a.png"), ("exp4", "blank", "no shape found"),
    ("exp3", "huge", "4097 x 8"), ("exp1", "one", "at least 2"), ("exp2", "file", "not a folder"),
    ("exp4", "missing", "not a folder")])
def test_bad_stimulus_folders_are_refused_before_training(tmp_path, capsys, no_training, exp, kind, needle):
    d = tmp_path / "nowhere" if kind == "missing" else _whole_folder(tmp_path, kind)
    refused(capsys, evaluating(tmp_path / "run", f"experiment={exp}", "stimuli=folder", f"stimuli.path={d}"), needle)
