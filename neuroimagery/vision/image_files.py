"""A user's image files, checked before they are used: every refusal names the file.

- :func:`list_images` lists a folder's PNG/JPEG files and refuses a link that leads nowhere (a
  broken link, a loop), which a plain listing would skip without a word;
- :func:`header_size` reads an image's size from its header alone, so a huge one is refused
  before it is decoded (:data:`MAX_IMAGE_SIDE`);
- :func:`read_image` decodes it completely: a truncated or corrupt file is refused (a decoder
  that stops early, e.g. libjpeg's "Premature end of JPEG file", would otherwise hand back a
  half-grey image), and returns its colour pixels with whether it is transparent anywhere (its
  alpha channel varies), so a shape drawn only in the transparency can be named as such.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..core.errors import UserInputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
MAX_IMAGE_SIDE = 4096  # pixels: a larger user image is refused by name (decoding it costs memory)
MAX_FOLDER_IMAGES = 500  # images in one user stimulus folder


def list_images(folder: str | os.PathLike) -> list[Path]:
    """The PNG/JPEG files of ``folder``, sorted; a link among them that leads to no file is refused."""
    folder = Path(folder)
    out = []
    for p in sorted(folder.iterdir()):
        if p.suffix.lower() not in IMAGE_SUFFIXES:
            continue
        if p.is_symlink():
            try:
                p.resolve(strict=True)
            except RuntimeError:  # Python < 3.13: a loop
                raise UserInputError(f"image {p} is a symbolic link that loops back on itself") from None
            except OSError as err:
                why = "loops back on itself" if "loop" in str(err).lower() or err.errno == 40 else "leads to no file"
                raise UserInputError(f"image {p} is a symbolic link that {why}") from None
        if p.is_file():
            out.append(p)
    return out


def header_size(path: Path) -> tuple[int, int]:
    """Width and height of an image from its header alone (nothing is decoded)."""
    import warnings

    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():  # the size is judged here, by MAX_IMAGE_SIDE
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                return im.size
    except Image.DecompressionBombError:
        raise UserInputError(f"image {path} is too large to decode") from None
    except (UnidentifiedImageError, OSError, ValueError) as err:
        raise UserInputError(f"cannot read image {path}: not a valid PNG or JPEG file ({err})") from None


def check_size(path: Path) -> tuple[int, int]:
    """:func:`header_size`, refusing an image with a side over :data:`MAX_IMAGE_SIDE`."""
    w, h = header_size(path)
    if max(w, h) > MAX_IMAGE_SIDE:
        raise UserInputError(f"image {path} is {w} x {h} pixels; at most {MAX_IMAGE_SIDE} x {MAX_IMAGE_SIDE}")
    return w, h


def read_image(path: Path) -> tuple[np.ndarray, bool]:
    """``(BGR uint8 pixels (H, W, 3), transparent)`` of a completely decodable image (see the
    module docstring); the size is checked from the header first."""
    import cv2
    from PIL import Image

    check_size(path)
    try:
        with Image.open(path) as im:
            im.load()  # the whole file: a truncated one raises here (ImageFile.LOAD_TRUNCATED_IMAGES is off)
            transparent = False
            if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
                alpha = np.asarray(im.convert("RGBA"))[..., 3]
                transparent = bool(alpha.min() != alpha.max())
    except Image.DecompressionBombError:
        raise UserInputError(f"image {path} is too large to decode") from None
    except (OSError, ValueError, SyntaxError) as err:  # PIL's errors for a truncated or corrupt file
        raise UserInputError(f"cannot read image {path}: it cannot be fully decoded ({err})") from None
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)  # the pixels, as before: cv2's decoders
    if img is None or img.size == 0:
        raise UserInputError(f"cannot read image {path}: not a valid PNG or JPEG file")
    return img, transparent
