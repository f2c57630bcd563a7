"""Pressure-film images → contact maps on a joint's grid (paper §3.1, Eqs. 23–24; §5, Fig. 11).

A film scan is read as a grayscale float matrix (Eq. 23) and sampled at the flank's grid nodes. The result
keeps two views of the film at the nodes: a normalised **darkness** map (what the PCA sampler works on,
Eq. 24 vectorises it) and a boolean **contact** grid (a threshold on image intensity, Fig. 11).

Orientation (the convention of :mod:`lab.films` and docs/campaign.md, "Film images")
--------------------------------------------------------------------------------------
* image **rows** run along grid rows (axial), image **columns** along grid columns (radial, outwards): the
  slot bottom is the **left** edge of the imprint;
* grid node (0, 0) sits at pixel ``geometry.origin`` = (row, col), and node (i, j) at
  ``origin + (i · spacing[0], j · spacing[1]) / pixel_size``;
* pixel (r, c) covers [r − ½, r + ½] × [c − ½, c + ½] (pixel-centre convention), so a node's gray value is the
  bilinear interpolation of the four pixel centres around it;
* **dark = high pressure**: a node is in contact where its gray value is **below** the threshold.

Without geometry (a lab film that comes with no metadata) the reader places the grid itself: the imprint
(``fallback="imprint"``: the bounding box of the exposed pixels) or the whole image (``fallback="image"``:
a scan already cropped to the flank, as the paper's "standardized height and width", Eq. 23) is taken as
the nodes' cells, the node box widened by half a spacing on every side, so every node is a cell centre.

Tone
----
``gray = clip((white − value) / white, 0, 1)``: 0 is unexposed film, 1 is black (gray value 0). ``white`` is
the unexposed film's gray value: given (``FilmMeta.white``) or estimated as the median of the brightest 5 %
of the pixels. The scale is fixed by the film and scanner, not stretched per image, so that maps of different
joints are comparable for PCA.

Threshold
---------
The user's value (e.g. ``FilmMeta.contact_level``, in the image's gray units), or else Otsu's threshold
(:func:`identify.film_image.otsu_threshold`) on the pixels of the nodes' cells. The value used and its source
are reported.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import map_coordinates

from rom.contact import ContactPattern

from .errors import IdentifyError
from .film_checks import check_imprint_in_cells, check_imprint_in_frame, match_gray_scale, rotation_visible
from .film_image import find_imprint, load_image, otsu_threshold, unexposed_level

__all__ = [
    "FilmGeometry",
    "FilmMap",
    "orientation_checked",
    "MIN_PIXELS_PER_SPACING",
    "contact_pattern",
    "map_film",
    "read_film",
]

#: A grid spacing must span at least this many pixels: below it two neighbouring nodes read the same pixels
#: (Nyquist: an alternating contact pattern needs two pixels per node).
MIN_PIXELS_PER_SPACING = 2.0

_FALLBACKS = ("imprint", "image")


def _pair(name: str, value, positive: bool) -> tuple[float, float]:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise IdentifyError(f"film geometry: {name} must be two numbers, got {value!r}") from None
    if a.shape != (2,) or not np.isfinite(a).all() or (positive and not (a > 0).all()):
        what = "two positive finite numbers" if positive else "two finite numbers"
        raise IdentifyError(f"film geometry: {name} must be {what}, got {value!r}")
    return float(a[0]), float(a[1])


def _grid(grid, where: str = "grid") -> tuple[int, int]:
    if isinstance(grid, (str, bytes)):
        raise IdentifyError(f"{where} must be (rows, cols), two positive integers, got {grid!r}")
    try:
        g = tuple(int(x) for x in grid)
        ok = len(g) == 2 and all(int(x) == x for x in grid) and min(g) >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise IdentifyError(f"{where} must be (rows, cols), two positive integers, got {grid!r}")
    return g


@dataclass(frozen=True)
class FilmGeometry:
    """Where the grid nodes lie on a film image.

    Attributes
    ----------
    origin : (float, float)
        Pixel (row, col) of grid node (0, 0), pixel-centre convention (may be fractional).
    spacing : (float, float)
        Grid spacing along rows (axial, between grid rows) and columns (radial, between grid columns), in the
        unit of ``pixel_size`` (m for :class:`lab.films.FilmMeta`; pixels when ``pixel_size`` is 1).
    pixel_size : float
        Size of a square pixel, same unit as ``spacing``. Default 1 (spacing in pixels).
    grid : (int, int) or None
        The grid shape the geometry was made for, if known; :func:`map_film` refuses another grid.
    """

    origin: tuple[float, float]
    spacing: tuple[float, float]
    pixel_size: float = 1.0
    grid: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", _pair("origin", self.origin, positive=False))
        object.__setattr__(self, "spacing", _pair("spacing", self.spacing, positive=True))
        ps = self.pixel_size
        if isinstance(ps, bool) or not isinstance(ps, (int, float, np.number)) or not (math.isfinite(ps) and ps > 0):
            raise IdentifyError(f"film geometry: pixel_size must be a positive finite number, got {ps!r}")
        object.__setattr__(self, "pixel_size", float(ps))
        if self.grid is not None:
            object.__setattr__(self, "grid", _grid(self.grid, "film geometry: grid"))

    @classmethod
    def from_mapping(cls, meta) -> FilmGeometry:
        """Geometry from film metadata: a mapping (a manifest's ``[[films]]`` entry, ``FilmMeta.to_dict()``) or
        an object with the same attributes (``lab.films.FilmMeta``).

        Reads ``origin``, ``spacing``, ``pixel_size`` and, if present, ``grid``; other keys are ignored.
        """
        get = meta.get if isinstance(meta, Mapping) else (lambda k, d=None: getattr(meta, k, d))
        missing = [k for k in ("origin", "spacing", "pixel_size") if get(k) is None]
        if missing:
            raise IdentifyError(f"film metadata lacks {', '.join(missing)} (needs origin, spacing, pixel_size)")
        return cls(tuple(get("origin")), tuple(get("spacing")), get("pixel_size"), get("grid"))

    def pixels_per_spacing(self) -> tuple[float, float]:
        """Grid spacing in pixels along rows and columns."""
        return self.spacing[0] / self.pixel_size, self.spacing[1] / self.pixel_size

    def node_pixels(self, grid: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Fractional pixel (row, col) of every node, each of shape ``grid``: origin + (i, j) · spacing / pixel_size."""
        rows, cols = _grid(grid)
        sr, sc = self.pixels_per_spacing()
        i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        return self.origin[0] + i * sr, self.origin[1] + j * sc


@dataclass(frozen=True, eq=False)
class FilmMap:
    """A film read onto a flank's grid.

    Attributes
    ----------
    gray : ndarray of float64, shape (rows, cols)
        Darkness at the nodes, clip((white − value) / white, 0, 1): 0 unexposed, 1 black (Eq. 23 on the grid).
    contact : ndarray of bool, shape (rows, cols)
        ``value < threshold`` (dark = high pressure).
    values : ndarray of float64, shape (rows, cols)
        Gray value at each node in the image's own units (bilinear between pixel centres).
    threshold : float
        Contact threshold in the image's gray units.
    threshold_source : {"given", "otsu"}
    level : float
        The threshold on the ``gray`` scale, (white − threshold) / white: ``contact == (gray > level)``
        wherever ``level`` lies in (0, 1) (the PCA sampler thresholds synthetic maps on this scale).
    white : float
        Unexposed film gray value used for ``gray``.
    geometry : FilmGeometry
        Node placement used (given, or found by the fallback, then in pixels).
    geometry_source : {"given", "imprint", "image"}
    image_shape : (int, int)
        (height, width) of the image in pixels.
    path : str or None
        The file read, if any.
    """

    gray: np.ndarray
    contact: np.ndarray
    values: np.ndarray
    threshold: float
    threshold_source: str
    level: float
    white: float
    geometry: FilmGeometry
    geometry_source: str
    image_shape: tuple[int, int]
    path: str | None = None

    @property
    def grid(self) -> tuple[int, int]:
        """Grid shape (rows, cols)."""
        return self.gray.shape

    @property
    def contact_fraction(self) -> float:
        """Share of the grid nodes in contact."""
        return float(self.contact.mean())

    @property
    def name(self) -> str:
        """The file name for messages (``<array>`` for an image passed as an array)."""
        return self.path if self.path is not None else "<array>"


def _box_geometry(box: tuple[float, float, float, float], grid: tuple[int, int]) -> FilmGeometry:
    """Geometry that makes ``box`` (top, bottom, left, right pixel edges) the nodes' cells: node (i, j) at the
    centre of cell (i, j) of a rows × cols division of the box."""
    top, bottom, left, right = box
    rows, cols = grid
    sr, sc = (bottom - top) / rows, (right - left) / cols
    return FilmGeometry(origin=(top + 0.5 * sr, left + 0.5 * sc), spacing=(sr, sc), pixel_size=1.0, grid=grid)


def _imprint(image: np.ndarray, white: float) -> tuple[float, float, float, float]:
    try:
        return find_imprint(image, white)
    except IdentifyError as e:
        raise IdentifyError(f"blank film, {e}") from None


def _cells_box(geometry: FilmGeometry, grid: tuple[int, int]) -> tuple[float, float, float, float]:
    """(top, bottom, left, right) pixel edges of the nodes' cells: the node box widened by half a spacing."""
    sr, sc = geometry.pixels_per_spacing()
    top, left = geometry.origin[0] - 0.5 * sr, geometry.origin[1] - 0.5 * sc
    return top, top + grid[0] * sr, left, left + grid[1] * sc


def orientation_checked(film: FilmMap) -> bool:
    """Whether reading ``film`` could have seen a scan rotated by 90° (its geometry given, its cells' box not
    square); where it could not, the scan was read as given (image rows along the grid's rows)."""
    if film.geometry_source != "given":
        return False
    return rotation_visible(_cells_box(film.geometry, film.gray.shape), film.geometry.pixels_per_spacing())


def _warn(path, note: str) -> None:
    if note:
        warnings.warn(f"film {path if path is not None else '<array>'}: {note}", UserWarning, stacklevel=4)


def _cells(image: np.ndarray, geometry: FilmGeometry, grid: tuple[int, int]) -> np.ndarray:
    """Pixels of the nodes' cells (node box widened by half a spacing), ignoring rotation: the Otsu sample."""
    r0, r1, c0, c1 = _cells_box(geometry, grid)
    h, w = image.shape
    ra, rb = max(0, math.ceil(r0)), min(h, math.floor(r1) + 1)
    ca, cb = max(0, math.ceil(c0)), min(w, math.floor(c1) + 1)
    return image[ra:rb, ca:cb]


def map_film(
    image: np.ndarray,
    grid: tuple[int, int],
    geometry: FilmGeometry | None = None,
    *,
    threshold: float | None = None,
    white: float | None = None,
    fallback: str = "imprint",
    path: str | os.PathLike | None = None,
    check: bool = True,
) -> FilmMap:
    """Sample a film image onto a flank's contact grid.

    Parameters
    ----------
    image : array_like of float, shape (height, width)
        Gray values (:func:`identify.film_image.load_image`), oriented as described in the module docstring.
    grid : (int, int)
        Grid shape (rows, cols), e.g. (7, 31).
    geometry : FilmGeometry, optional
        Node placement (:meth:`FilmGeometry.from_mapping` on the film's metadata). Without it the grid is
        placed by ``fallback``.
    threshold : float, optional
        Contact threshold in the image's gray units (``FilmMeta.contact_level``): contact where the node's gray
        value is below it. Default: Otsu's threshold on the pixels of the nodes' cells.
    white : float, optional
        Unexposed film gray value (``FilmMeta.white``). Default: :func:`identify.film_image.unexposed_level`.
    fallback : {"imprint", "image"}
        Without geometry, the nodes' cells are the imprint's bounding box
        (:func:`identify.film_image.find_imprint`) or the whole image (a scan cropped to the flank). Ignored when
        ``geometry`` is given.
    path : str or path-like, optional
        The image's file, for messages and the result.
    check : bool
        Compare the image with its metadata first (:mod:`identify.film_checks`: gray scale, blank film, imprint
        inside the grid's cells or the frame). Default True; off only for arrays that are not film scans.

    Returns
    -------
    FilmMap

    Raises
    ------
    IdentifyError
        For an image that is not 2-D, a bad grid or geometry, a geometry made for another grid, a grid too fine
        for the pixels (fewer than :data:`MIN_PIXELS_PER_SPACING` pixels per spacing), nodes outside the
        image, a blank film (fallback "imprint"), or a bad threshold or white level. Each message names the
        file.
    """
    name = str(path) if path is not None else "<array>"
    try:
        return _map_film(image, grid, geometry, threshold, white, fallback, path, check)
    except IdentifyError as e:
        raise IdentifyError(f"film {name}: {e}") from None


def _map_film(image, grid, geometry, threshold, white, fallback, path, check) -> FilmMap:
    a = np.asarray(image)
    if a.ndim != 2 or min(a.shape) < 2:
        raise IdentifyError(f"expected a 2-D grayscale image of at least 2×2 pixels, got shape {a.shape}")
    if a.dtype.kind not in "iuf" or not np.isfinite(a).all():
        raise IdentifyError(f"image must hold finite numbers, got dtype {a.dtype}")
    a = a.astype(np.float64, copy=False)
    grid = _grid(grid)
    rows, cols = grid
    if fallback not in _FALLBACKS:
        raise IdentifyError(f"fallback must be one of {', '.join(map(repr, _FALLBACKS))}, got {fallback!r}")
    if white is None:
        w = unexposed_level(a)
    else:
        w = float(white)
        if not (math.isfinite(w) and w > 0):
            raise IdentifyError(f"white (unexposed gray level) must be positive and finite, got {white!r}")
    if not w > 0:
        raise IdentifyError("the image is black: no unexposed film to scale the gray values by")
    if check and white is not None:  # the scan against its metadata's gray scale: refused, or read as stated
        t_given = threshold if isinstance(threshold, int | float) and math.isfinite(threshold) else None
        a, note = match_gray_scale(a, w, unexposed_level(a), t_given)
        _warn(path, note)

    if geometry is not None:
        if not isinstance(geometry, FilmGeometry):
            raise IdentifyError(f"geometry must be a FilmGeometry, got {type(geometry).__name__}")
        if geometry.grid is not None and geometry.grid != grid:
            raise IdentifyError(f"the film's metadata is for a {geometry.grid[0]}×{geometry.grid[1]} grid, "
                                f"the model's grid is {rows}×{cols}")
        geo, source = geometry, "given"
        if check:
            check_imprint_in_cells(_imprint(a, w), _cells_box(geo, grid), geo.pixels_per_spacing(), geo.pixel_size)
    elif fallback == "image":
        geo, source = _box_geometry((-0.5, a.shape[0] - 0.5, -0.5, a.shape[1] - 0.5), grid), "image"
    else:
        box = _imprint(a, w)
        if check:
            _warn(path, check_imprint_in_frame(box, a.shape))
        geo, source = _box_geometry(box, grid), "imprint"

    sr, sc = geo.pixels_per_spacing()
    for axis, n, s in (("row", rows, sr), ("column", cols, sc)):
        if n > 1 and s < MIN_PIXELS_PER_SPACING:
            raise IdentifyError(f"grid {rows}×{cols} is too fine for the image ({a.shape[0]}×{a.shape[1]} pixels): "
                                f"{s:.3g} pixels per {axis} spacing, needs ≥ {MIN_PIXELS_PER_SPACING:g}")
    r, c = geo.node_pixels(grid)
    outside = (r < -0.5) | (r > a.shape[0] - 0.5) | (c < -0.5) | (c > a.shape[1] - 0.5)
    if outside.any():
        i, j = np.argwhere(outside)[0]
        raise IdentifyError(f"grid node ({i}, {j}) falls at pixel ({r[i, j]:.1f}, {c[i, j]:.1f}), outside the "
                            f"{a.shape[0]}×{a.shape[1]} image ({int(outside.sum())} node(s) outside)")
    # Bilinear between pixel centres; "nearest" extends edge pixels over the outer half pixel.
    values = map_coordinates(a, [r.ravel(), c.ravel()], order=1, mode="nearest").reshape(grid)

    if threshold is None:
        t, t_source = otsu_threshold(_cells(a, geo, grid)), "otsu"
    else:
        t, t_source = float(threshold), "given"
        if not math.isfinite(t):
            raise IdentifyError(f"threshold must be a finite gray value, got {threshold!r}")
    contact = values < t
    if not contact.any() or contact.all():
        state = "no node is" if not contact.any() else "every node is"
        warnings.warn(f"film {path if path is not None else '<array>'}: {state} in contact at threshold {t:.6g} "
                      f"(node gray values {values.min():.6g}–{values.max():.6g})", stacklevel=3)
    gray = np.clip((w - values) / w, 0.0, 1.0)
    for x in (gray, contact, values):
        x.flags.writeable = False
    return FilmMap(
        gray=gray, contact=contact, values=values, threshold=t, threshold_source=t_source, level=(w - t) / w,
        white=w, geometry=geo, geometry_source=source, image_shape=(int(a.shape[0]), int(a.shape[1])),
        path=None if path is None else str(path),
    )


def read_film(
    path: str | os.PathLike,
    grid: tuple[int, int],
    geometry: FilmGeometry | None = None,
    *,
    threshold: float | None = None,
    white: float | None = None,
    fallback: str = "imprint",
) -> FilmMap:
    """Read a film scan and sample it onto a flank's contact grid: :func:`identify.film_image.load_image`, then
    :func:`map_film`.

    With the metadata of a virtual campaign's ``[[films]]`` entry ``m``::

        read_film(path, (7, 31), FilmGeometry.from_mapping(m), threshold=m["contact_level"], white=m["white"])

    and for a lab film without metadata, ``read_film(path, (7, 31))`` (imprint bounding box, Otsu threshold).
    See :func:`map_film` for the parameters and errors.
    """
    return map_film(load_image(path), grid, geometry, threshold=threshold, white=white, fallback=fallback,
                    path=path)


def contact_pattern(left: FilmMap, right: FilmMap) -> ContactPattern:
    """The contact pattern of a joint from its two flanks' films.

    Parameters
    ----------
    left, right : FilmMap
        The L and R flank films of one joint, on the same grid.

    Returns
    -------
    rom.contact.ContactPattern

    Raises
    ------
    IdentifyError
        If the grids differ, or the pattern is not a valid joint (no contact, or all contacts on a line).
    """
    if left.grid != right.grid:
        raise IdentifyError(f"films {left.name} (L) and {right.name} (R) are on different grids: "
                            f"{left.grid} and {right.grid}")
    try:
        return ContactPattern(left.contact, right.contact)
    except ValueError as e:
        raise IdentifyError(f"films {left.name} (L) and {right.name} (R): {e}") from None
