"""Sanity checks of a film scan against its metadata, before it is read onto the grid (issue 30, item 4).

A film that does not match its metadata still gives a contact grid, silently wrong: an all-white or all-black
scan reads 0 % or 100 % contact, a 16-bit scan of 8-bit metadata reads 0 %, a rotated scan or a wrong
``pixel_size`` reads another pattern. These checks compare what the image itself shows with what its metadata
says, and either refuse the film with one line naming the field at fault, or read it under a stated
interpretation (a warning that reaches ``summary.json``).

The checks
----------
* **Gray scale** (with ``white`` given): the image's unexposed level (:func:`identify.film_image.unexposed_level`)
  must agree with ``white`` within :data:`WHITE_RATIO`. An image whose level is ``white`` × 257 or × 256 (a
  16-bit scan of a film whose metadata is in 8-bit levels) is read on the metadata's scale, with a warning. An
  image with no pixel as bright as ``contact_level`` has no unexposed film at all (all black).
* **Imprint present**: some pixels are exposed (:func:`identify.film_image.find_imprint`); a blank film is refused.
* **Imprint inside the grid's cells** (with geometry given): the imprint cannot extend beyond the flank, so
  its bounding box must lie inside the nodes' cells (node box widened by half a spacing), within
  :func:`imprint_tolerance`. A box that is the cells' box transposed is a scan rotated by 90°; one larger in
  both axes by about the same factor is a wrong ``pixel_size`` (or ``spacing``): both are named as such.
* **Imprint inside the frame** (grid placed on the imprint, no geometry): an imprint that reaches every edge
  of the image has no unexposed film around it (an all-black scan, or one cropped inside the imprint) and is
  refused; one that reaches some edges is read with a warning, since the scan may cut it.

A 90° rotation cannot be seen when the cells' box is square (:func:`rotation_visible`): such films are read
as scanned, and `bladetwin run` names them in a note. Nothing here checks an imprint smaller than the cells'
box: a flank whose edge rows carry no pressure looks the same as a ``pixel_size`` too small.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import IdentifyError

__all__ = ["WHITE_RATIO", "BIT_DEPTH_FACTORS", "MAX_ROTATION_DEG", "EDGE_PIXELS", "match_gray_scale",
           "imprint_tolerance", "check_imprint_in_cells", "rotation_visible", "check_imprint_in_frame"]

#: The scan's unexposed level and the metadata's ``white`` may differ by at most this factor: the same film
#: stock on the same scanner does not change its white by 2×, while a scan of another bit depth or an
#: all-black scan is off by far more.
WHITE_RATIO = 2.0
#: 8-bit levels → 16-bit: × 257 (65535 / 255, the usual conversion) or × 256 (a bit shift).
BIT_DEPTH_FACTORS = (257.0, 256.0)
#: Largest scan rotation the imprint-box check allows for: each edge of a rotated imprint moves out by half the
#: other extent × tan θ. Far above a placed film's misregistration (lab.films: 0.5°).
MAX_ROTATION_DEG = 2.0
#: Blur and grain move a box edge found at half the exposed share by about a pixel; allow two.
EDGE_PIXELS = 2.0


def match_gray_scale(image: np.ndarray, white: float, level: float, threshold: float | None) -> tuple[np.ndarray, str]:
    """The image on the metadata's gray scale, or :class:`IdentifyError` where the two cannot be matched.

    Parameters
    ----------
    image : ndarray of float64, shape (height, width)
    white : float
        The metadata's unexposed gray level.
    level : float
        The image's own unexposed level (:func:`identify.film_image.unexposed_level`).
    threshold : float or None
        The metadata's ``contact_level``, if any.

    Returns
    -------
    image : ndarray of float64, shape (height, width)
        ``image`` itself, or divided by the bit-depth factor that matches it to ``white``.
    note : str
        Empty, or the interpretation taken (for a warning).
    """
    ratio = level / white
    if 1.0 / WHITE_RATIO <= ratio <= WHITE_RATIO:
        if threshold is not None and level <= threshold:
            raise IdentifyError(f"contact_level = {threshold:g}: the image's unexposed level ({level:.6g}) is not "
                                "above it, so every pixel reads as contact (an all-black or under-exposed scan?)")
        return image, ""
    for k in BIT_DEPTH_FACTORS:
        if 1.0 / 1.05 <= ratio / k <= 1.05:
            return image / k, (f"its unexposed level is {level:.6g}, {ratio:.1f} × the metadata's white = {white:g}: "
                               f"read as a 16-bit scan of 8-bit metadata (gray values divided by {k:g})")
    if ratio < 1.0:
        raise IdentifyError(f"white = {white:g}, but the image's brightest pixels are at {level:.6g}: no unexposed "
                            "film in the scan (all black or under-exposed), or the metadata is for another scan")
    raise IdentifyError(f"white = {white:g}, but the image's unexposed level is {level:.6g} ({ratio:.3g} ×): the gray "
                        "levels in the metadata are for another scanner setting or bit depth")


def imprint_tolerance(spacing_px: float, across_px: float) -> float:
    """How far (pixels) an imprint's box edge may lie outside the nodes' cells.

    Half a grid spacing (the cells reach half a spacing beyond the outer nodes; a flank whose edge is the
    outer node line ends there), the reach of a :data:`MAX_ROTATION_DEG` rotation over half the other extent
    ``across_px``, and :data:`EDGE_PIXELS`.
    """
    return 0.5 * spacing_px + 0.5 * across_px * math.tan(math.radians(MAX_ROTATION_DEG)) + EDGE_PIXELS


def _extent(box: tuple[float, float, float, float]) -> tuple[float, float]:
    top, bottom, left, right = box
    return bottom - top, right - left


def check_imprint_in_cells(imprint: tuple[float, float, float, float], cells: tuple[float, float, float, float],
                           spacing_px: tuple[float, float], pixel_size: float) -> None:
    """Refuse an imprint that reaches beyond the grid's cells by more than :func:`imprint_tolerance`.

    Parameters
    ----------
    imprint, cells : (top, bottom, left, right)
        Pixel edges of the imprint's bounding box and of the nodes' cells (pixel-centre convention).
    spacing_px : (float, float)
        Grid spacing in pixels along rows and columns.
    pixel_size : float
        The metadata's pixel size, for the message.
    """
    (h, w), (ch, cw) = _extent(imprint), _extent(cells)
    tol_r, tol_c = imprint_tolerance(spacing_px[0], cw), imprint_tolerance(spacing_px[1], ch)
    over = {"top": cells[0] - imprint[0] - tol_r, "bottom": imprint[1] - cells[1] - tol_r,
            "left": cells[2] - imprint[2] - tol_c, "right": imprint[3] - cells[3] - tol_c}
    side = max(over, key=over.get)
    if over[side] <= 0:
        return
    what = (f"the imprint spans {h:.0f} × {w:.0f} pixels (rows × columns) but the grid's cells span {ch:.0f} × "
            f"{cw:.0f} at this origin, spacing and pixel_size")
    if abs(h - cw) <= 2 * tol_c and abs(w - ch) <= 2 * tol_r and rotation_visible(cells, spacing_px):
        raise IdentifyError(f"{what}: the scan looks rotated by 90°; rotate it so that image rows run along the "
                            "grid's rows (see the campaign's orientation note)")
    fr, fc = h / ch, w / cw
    if fr > 1 and fc > 1 and abs(fr - fc) <= 0.15 * max(fr, fc):
        f = math.sqrt(fr * fc)
        raise IdentifyError(f"pixel_size = {pixel_size:g}: {what}, {f:.2f} × larger; is pixel_size (or spacing) "
                            f"off? The imprint suggests pixel_size ≈ {pixel_size / f:.4g}")
    beyond = over[side] + (tol_r if side in ("top", "bottom") else tol_c)
    raise IdentifyError(f"origin / spacing: {what}; the imprint reaches {beyond:.0f} pixels beyond their {side} edge")


def rotation_visible(cells: tuple[float, float, float, float], spacing_px: tuple[float, float]) -> bool:
    """Whether :func:`check_imprint_in_cells` can tell a 90° rotated scan: the cells' box, transposed, must differ
    from itself by more than the imprint's tolerance (the same test as the rotation message's).

    Parameters
    ----------
    cells : (top, bottom, left, right)
        Pixel edges of the nodes' cells.
    spacing_px : (float, float)
        Grid spacing in pixels along rows and columns.
    """
    ch, cw = _extent(cells)
    tol = max(imprint_tolerance(spacing_px[0], cw), imprint_tolerance(spacing_px[1], ch))
    return abs(ch - cw) > 2 * tol


def check_imprint_in_frame(imprint: tuple[float, float, float, float], shape: tuple[int, int]) -> str:
    """Refuse an imprint that fills the image; name the edges it touches (for a warning), else ``""``.

    Parameters
    ----------
    imprint : (top, bottom, left, right)
        Pixel edges of the imprint's bounding box.
    shape : (int, int)
        Image (height, width).
    """
    h, w = shape
    touches = [name for name, hit in (("top", imprint[0] <= 0.0), ("bottom", imprint[1] >= h - 1.0),
                                      ("left", imprint[2] <= 0.0), ("right", imprint[3] >= w - 1.0)) if hit]
    if len(touches) == 4:
        raise IdentifyError("the imprint fills the image up to every edge: there is no unexposed film around it "
                            "(an all-black scan, or one cropped inside the imprint)")
    if touches:
        return (f"the imprint touches the image's {' and '.join(touches)} edge{'s' if len(touches) > 1 else ''}: "
                "the scan may cut it, and the grid is placed on what is visible")
    return ""

