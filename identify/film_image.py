"""A film scan as an image: its gray values (Eq. 23), its unexposed level, its imprint, and Otsu's threshold.

Nothing here knows the flank's grid: :mod:`identify.film` places the grid on the image and samples it.
Gray values stay in the image's own units (0–255 for 8-bit, 0–65535 for 16-bit scans); dark = exposed.
"""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from .errors import IdentifyError

__all__ = [
    "load_image",
    "otsu_threshold",
    "unexposed_level",
    "find_imprint",
    "IMPRINT_DEPTH",
    "IMPRINT_MIN_SHARE",
    "WHITE_SHARE",
]

#: A pixel is exposed (part of the imprint, for the fallback placement) where it is darker than the unexposed
#: level by more than this fraction of it: ~7 gray levels of 8-bit film, far above scanner grain (σ ≈ 1–2).
IMPRINT_DEPTH = 0.03

#: A row or column belongs to the imprint's bounding box if at least this fraction of its pixels (and at
#: least 2) are exposed; isolated dark specks (dust, grain) do not stretch the box.
IMPRINT_MIN_SHARE = 0.02

#: Share of the brightest pixels whose median estimates the unexposed film level.
WHITE_SHARE = 0.05


def _gray_array(im: Image.Image) -> np.ndarray:
    """Pixel values of a Pillow image as float64 (height, width), in the image's own gray units.

    8- and 16-bit grayscale, 32-bit integer and float images keep their values; colour and palette images are
    converted to luma (ITU-R 601, Pillow's "L"); an alpha channel is ignored.
    """
    if im.mode in ("L", "I", "F") or im.mode.startswith("I;16"):
        a = np.asarray(im)
    elif im.mode in ("LA", "La"):
        a = np.asarray(im.getchannel(0))
    else:
        a = np.asarray(im.convert("L"))
    return a.astype(np.float64)


def load_image(path: str | os.PathLike) -> np.ndarray:
    """Read a film scan (PNG or TIFF; any raster format Pillow reads) as a grayscale float matrix (Eq. 23).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    ndarray of float64, shape (height, width)
        Gray values in the image's own units (0–255 for 8-bit, 0–65535 for 16-bit scans); colour scans are
        converted to luma. A multi-page TIFF gives its first page (with a warning).

    Raises
    ------
    IdentifyError
        If the file is missing, not an image, truncated or corrupt, or not a 2-D image of at least 2×2 pixels.
    """
    p = Path(path)
    try:
        with Image.open(p) as im:
            n_frames = getattr(im, "n_frames", 1)
            if n_frames > 1:
                warnings.warn(f"film {p}: {n_frames} pages, reading the first", stacklevel=2)
            im.load()  # decode now: a truncated file fails here, not later
            a = _gray_array(im)
    except FileNotFoundError:
        raise IdentifyError(f"film {p}: no such file") from None
    except IsADirectoryError:
        raise IdentifyError(f"film {p}: is a folder, expected an image file") from None
    except UnidentifiedImageError:
        raise IdentifyError(f"film {p}: not an image (expected a PNG or TIFF scan)") from None
    except Image.DecompressionBombError as e:  # Pillow's guard against huge images, not an OSError
        raise IdentifyError(f"film {p}: image too large to read safely ({e})") from None
    except (OSError, SyntaxError, ValueError, EOFError) as e:  # Pillow's ways of saying "corrupt or truncated"
        raise IdentifyError(f"film {p}: unreadable or corrupt image ({e})") from None
    if a.ndim != 2 or min(a.shape) < 2:
        raise IdentifyError(f"film {p}: expected a 2-D grayscale image of at least 2×2 pixels, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise IdentifyError(f"film {p}: image holds non-finite values (NaN or inf)")
    return a


def otsu_threshold(values: np.ndarray, bins: int = 256) -> float:
    """Otsu's threshold: the split of a histogram that maximises the between-class variance.

    Parameters
    ----------
    values : array_like of float
        Gray values (any shape).
    bins : int
        Histogram bins over [min, max]. Default 256 (one per level of 8-bit data spanning the full range).

    Returns
    -------
    float
        t such that the classes are ``values < t`` and ``values >= t``: a bin edge. Where several splits tie
        (empty bins between the modes), the middle of the tied run, i.e. the middle of the gap.

    Raises
    ------
    IdentifyError
        If there are no finite values or they are all equal (nothing to split).

    Notes
    -----
    For the split after bin k, with class weights ω₀, ω₁ and means μ₀, μ₁, the between-class variance is
    σ_b² = ω₀ ω₁ (μ₀ − μ₁)² (Otsu, IEEE Trans. SMC 9(1), 1979); the class means use the bin centres.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0 or v.min() == v.max():
        raise IdentifyError("automatic threshold: the gray values are all equal, there is nothing to split")
    counts, edges = np.histogram(v, bins=bins)
    centres = 0.5 * (edges[:-1] + edges[1:])
    w0 = np.cumsum(counts)[:-1].astype(np.float64)  # weight of class 0 = bins 0..k, for k = 0..bins−2
    s0 = np.cumsum(counts * centres)[:-1]
    n, s = float(counts.sum()), float((counts * centres).sum())
    w1 = n - w0
    with np.errstate(divide="ignore", invalid="ignore"):
        sb = np.where((w0 > 0) & (w1 > 0), w0 * w1 * (s0 / w0 - (s - s0) / w1) ** 2, -np.inf)
    best = np.flatnonzero(sb >= sb.max() * (1 - 1e-12))
    run_end = best[0]
    while run_end + 1 in best:  # first contiguous run of tied splits
        run_end += 1
    k = 0.5 * (best[0] + run_end)
    # Threshold = upper edge of bin k (class 0 = values below it); fractional k lands mid-gap.
    return float(np.interp(k + 1, np.arange(edges.size), edges))


def unexposed_level(image: np.ndarray) -> float:
    """Estimate the unexposed film's gray value: the median of the brightest :data:`WHITE_SHARE` of the pixels.

    The margin of unexposed film around an imprint (and unexposed islands inside it) is the image's brightest
    part; a median over its top rather than the maximum keeps grain and dust out.
    """
    a = np.asarray(image, dtype=np.float64).ravel()
    k = max(1, int(math.ceil(WHITE_SHARE * a.size)))
    return float(np.median(np.partition(a, a.size - k)[a.size - k:]))


def find_imprint(image: np.ndarray, white: float | None = None) -> tuple[float, float, float, float]:
    """Bounding box of a film's imprint (its exposed pixels), as pixel edges.

    Parameters
    ----------
    image : ndarray, shape (height, width)
        Gray values; dark = exposed.
    white : float, optional
        Unexposed film level; estimated with :func:`unexposed_level` if not given.

    Returns
    -------
    top, bottom, left, right : float
        Box edges in pixel coordinates (pixel-centre convention): the box spans rows r0..r1 and columns c0..c1
        of exposed pixels, so ``top = r0 − ½``, ``bottom = r1 + ½`` and likewise for columns.

    Raises
    ------
    IdentifyError
        If no row or column holds exposed pixels (a blank film).

    Notes
    -----
    A pixel is exposed where it is darker than ``white · (1 −`` :data:`IMPRINT_DEPTH` ``)``; a row (column)
    belongs to the box if at least :data:`IMPRINT_MIN_SHARE` of its pixels (and at least 2) are exposed.
    """
    a = np.asarray(image, dtype=np.float64)
    w = unexposed_level(a) if white is None else float(white)
    exposed = a < w * (1.0 - IMPRINT_DEPTH)
    share_r, share_c = exposed.mean(axis=1), exposed.mean(axis=0)  # profiles: exposed share per row, per column
    rows = np.flatnonzero(exposed.sum(axis=1) >= max(2, IMPRINT_MIN_SHARE * a.shape[1]))
    cols = np.flatnonzero(exposed.sum(axis=0) >= max(2, IMPRINT_MIN_SHARE * a.shape[0]))
    if rows.size == 0 or cols.size == 0:
        raise IdentifyError(f"no imprint found: no pixel is darker than {w * (1.0 - IMPRINT_DEPTH):.6g} "
                            f"({IMPRINT_DEPTH:.0%} below the unexposed level {w:.6g})")
    top, bottom = _edges(share_r, rows[0], rows[-1], cols[-1] - cols[0] + 1)
    left, right = _edges(share_c, cols[0], cols[-1], rows[-1] - rows[0] + 1)
    return top, bottom, left, right


def _edges(share: np.ndarray, first: int, last: int, across: int) -> tuple[float, float]:
    """Sub-pixel edges of an imprint along one axis, from its exposed-share profile.

    A straight edge that is rotated by θ (or blurred) makes the profile ramp up over ~across·tan θ pixels (plus
    the blur), symmetrically about the true edge, so a box from the first and last exposed pixels is too big
    by about that much. The edge is put where the profile crosses half its level just inside the ramp (the
    largest share within a ramp's width, 1° + 3 pixels, of the first exposed pixel), interpolated linearly.
    """
    ramp = math.ceil(across * math.tan(math.radians(1.0))) + 3

    def crossing(profile: np.ndarray, start: int) -> float:
        stop = min(start + 2 * ramp, profile.size)
        level = 0.5 * profile[start:stop].max()
        k = start + int(np.argmax(profile[start:stop] >= level))  # first pixel at or above half the level
        if k == 0 or profile[k - 1] >= level:
            return k - 0.5
        # Linear between the pixel centres k − 1 (below the level) and k: a sharp edge (share 0, then full)
        # lands on the pixel border k − ½, a ramp on its middle.
        frac = (level - profile[k - 1]) / (profile[k] - profile[k - 1])
        return k - 1 + frac

    lo = crossing(share, first)
    hi = share.size - 1 - crossing(share[::-1], share.size - 1 - last)
    return lo, hi
