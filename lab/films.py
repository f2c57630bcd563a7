"""Pressure-film images: a flank's true pressure field rendered as a scanned pressure-sensitive film.

Image orientation (the same for both flanks and every joint)
-------------------------------------------------------------
The image is an 8-bit grayscale array ``image[row, col]`` laid out like the contact grid ``grid[i, j]``:

* image **rows** run along grid rows, the **axial** direction: the row index grows with u (the blade's
  local z, from the z = −t/2 face at the top to the z = +t/2 face at the bottom);
* image **columns** run along grid columns, **radially outward** along the slot wall: the **slot bottom is
  the left edge** of the imprint, the rim the right edge;
* grid node (0, 0), the slot-bottom node on the z = −t/2 face, sits near the **top-left** corner of the
  imprint, on the centre of pixel ``FilmMeta.origin`` = (row, col); node (i, j) sits at the (fractional)
  pixel position ``origin + (i · spacing[0], j · spacing[1]) / pixel_size``.

Pixel positions use the pixel-centre convention: pixel (r, c) covers [r − ½, r + ½] × [c − ½, c + ½]. Pixels
are square (``pixel_size`` m on both axes), with ``pixels_per_cell`` pixels across the smaller grid spacing.

Imprint
-------
The imprint covers the nodes' cells: the rectangle spanned by the grid nodes, widened by half a grid spacing
on every side, so every node (edge nodes included) is the centre of a block of pixels, as a reader that
reduces the image to the grid by block averaging assumes (paper §3.1). Around it lies a margin of unexposed
film (``FilmParams.margin_cells`` smaller grid spacings).

**Dark means high pressure.** The film's darkness follows the saturation curve D(p) = 1 − exp(−p / p_sat),
and the gray value is ``white − (white − black) · D(p)``: unexposed film (p = 0) is ``white``, saturated film
``black``. The gray value of the contact threshold pressure is ``FilmMeta.contact_level``; a reader marks a
pixel as contact where its value is **below** that level. The scan adds film grain (white noise) and then a
Gaussian blur (the scanner's optics), and rounds to uint8.

Misregistration: the imprint lies on the film slightly shifted (uniform, up to ``max_shift`` metres per
axis, a fraction of a grid cell) and rotated (uniform, up to ``max_rotation_deg``, about the imprint
centre) from its nominal place. ``origin`` is the nominal place, all a reader of a real film would know;
the applied shift and rotation are recorded in :class:`FilmMeta` as truth, for diagnostics only.

Reading films back into grids belongs to ``identify`` (which must work on real films), not here.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from PIL import Image
from scipy.ndimage import gaussian_filter

from ema.fileio import atomic_path

from .patterns import TruePressure

__all__ = ["FilmMeta", "FilmParams", "ORIENTATION", "render_film", "write_film"]

#: One-line statement of the image orientation (module docstring), stored with every film's metadata.
ORIENTATION = (
    "image rows = grid rows (axial, u increasing downwards); image columns = grid columns (radial, outwards "
    "to the right, slot bottom at the left edge); node (0, 0) at pixel `origin` (pixel-centre convention); "
    "dark = high pressure, contact where gray < contact_level"
)


@dataclass(frozen=True)
class FilmParams:
    """Film, scanner and placement parameters.

    Attributes
    ----------
    pixels_per_cell : int
        Pixels across the smaller grid spacing (pixels are square). Default 10.
    margin_cells : float
        Width of the unexposed margin around the imprint, in smaller grid spacings. Default 2.0.
    p_sat : float
        Saturation pressure (Pa) of the film's darkness curve D = 1 − exp(−p / p_sat). Default 60 MPa.
    white, black : float
        Gray values of unexposed (D = 0) and saturated (D = 1) film, 0..255. Defaults 235 and 25.
    grain : float
        Standard deviation (gray levels) of the film grain, white noise added before the blur. Default 2.0.
    blur : float
        Standard deviation (pixels) of the scanner's Gaussian blur. Default 1.0.
    max_shift : float
        Largest misregistration shift per axis (m); it must stay below half the smaller grid spacing (checked
        when rendering). Default 20 µm (5 % of the radial spacing of the academic 7×31 grid).
    max_rotation_deg : float
        Largest misregistration rotation (degrees, ≤ 1). Default 0.5.
    """

    pixels_per_cell: int = 10
    margin_cells: float = 2.0
    p_sat: float = 60e6
    white: float = 235.0
    black: float = 25.0
    grain: float = 2.0
    blur: float = 1.0
    max_shift: float = 20e-6
    max_rotation_deg: float = 0.5

    def __post_init__(self) -> None:
        if not (isinstance(self.pixels_per_cell, int) and self.pixels_per_cell >= 2):
            raise ValueError(f"pixels_per_cell must be an integer ≥ 2, got {self.pixels_per_cell!r}")
        if not (math.isfinite(self.p_sat) and self.p_sat > 0):
            raise ValueError(f"p_sat must be a positive pressure in Pa, got {self.p_sat!r}")
        if not 0.0 <= self.black < self.white <= 255.0:
            raise ValueError(f"gray levels must satisfy 0 ≤ black < white ≤ 255, got black={self.black}, "
                             f"white={self.white}")
        for name in ("margin_cells", "grain", "blur", "max_shift"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be ≥ 0 and finite, got {v!r}")
        if not 0.0 <= self.max_rotation_deg <= 1.0:
            raise ValueError(f"max_rotation_deg must lie in [0, 1] degrees, got {self.max_rotation_deg}")

    def gray(self, p: np.ndarray) -> np.ndarray:
        """Noise-free gray value (float) of pressure ``p`` (Pa): white − (white − black)(1 − exp(−p / p_sat))."""
        return self.white - (self.white - self.black) * -np.expm1(-np.asarray(p, np.float64) / self.p_sat)


@dataclass(frozen=True)
class FilmMeta:
    """What a film image shows and where (see the module docstring for the orientation).

    Attributes
    ----------
    joint : int
        Joint (slot) number, 1-based.
    flank : {"L", "R"}
    grid : (int, int)
        Grid shape (rows, cols).
    spacing : (float, float)
        Grid spacing (m): axial between rows, radial between columns.
    pixel_size : float
        Pixel size (m/pixel), the same on both axes.
    origin : (float, float)
        Nominal (row, col) pixel position of grid node (0, 0), pixel-centre convention.
    node_origin : (float, float)
        Physical (u, v) coordinates (m) of grid node (0, 0), in the frame of :class:`lab.patterns.TruePressure`.
    contact_level : float
        Gray value of the contact threshold pressure: contact where the image is below it.
    white : float
        Gray value of unexposed film (the margin's mean).
    threshold_pressure : float
        The contact threshold pressure (Pa).
    p_sat : float
        The film's saturation pressure (Pa).
    shift : (float, float)
        Applied misregistration shift (m) along (u, v): truth, unknown to a reader of real films.
    rotation : float
        Applied misregistration rotation θ (rad): truth, as ``shift``. A flank point x = (u, v) lies on the film
        at x_c + Rot(θ)(x − x_c) + shift, with x_c the centre of the node box and
        Rot(θ) = [[cos θ, −sin θ], [sin θ, cos θ]].
    orientation : str
        :data:`ORIENTATION`.
    """

    joint: int
    flank: str
    grid: tuple[int, int]
    spacing: tuple[float, float]
    pixel_size: float
    origin: tuple[float, float]
    node_origin: tuple[float, float]
    contact_level: float
    white: float
    threshold_pressure: float
    p_sat: float
    shift: tuple[float, float]
    rotation: float
    orientation: str = ORIENTATION

    def to_dict(self) -> dict:
        """Plain Python values (for a TOML or JSON manifest)."""
        return asdict(self)


def _spacing(truth: TruePressure) -> tuple[float, float]:
    """Grid spacing (du, dv) in m; the film layout needs a regular grid."""
    u, v = truth.u, truth.v
    rows, cols = truth.grid
    du, dv = np.ptp(u) / (rows - 1), np.ptp(v) / (cols - 1)
    tol = 1e-6 * max(np.ptp(u), np.ptp(v))
    ii, jj = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    regular = np.allclose(u, u[0, 0] + ii * du, rtol=0, atol=tol)
    regular = regular and np.allclose(v, v[0, 0] + jj * dv, rtol=0, atol=tol)
    if not regular:
        raise ValueError("film rendering needs a regular grid: u = u00 + i·du along rows, v = v00 + j·dv along columns")
    return float(du), float(dv)


def render_film(
    truth: TruePressure, joint: int, flank: str, rng: np.random.Generator, params: FilmParams | None = None
) -> tuple[np.ndarray, FilmMeta]:
    """Render one flank's true pressure field as a scanned pressure-film image.

    Parameters
    ----------
    truth : TruePressure
        The true pressure fields; its grid must be regular (the academic grids are).
    joint : int
        Joint (slot) number, 1..truth.n_joints.
    flank : {"L", "R"}
    rng : numpy.random.Generator
        Draws the misregistration, then the grain.
    params : FilmParams, optional

    Returns
    -------
    image : ndarray of uint8, shape (height, width)
        The scan, oriented as described in the module docstring.
    meta : FilmMeta
    """
    fp = params or FilmParams()
    thr = truth.contact_threshold(joint, flank)  # also validates joint and flank
    du, dv = _spacing(truth)
    rows, cols = truth.grid
    px = min(du, dv) / fp.pixels_per_cell
    margin = math.ceil(fp.margin_cells * fp.pixels_per_cell)
    # Imprint = node cells (node box widened by half a spacing), starting ~`margin` pixels in. Node (0, 0) sits
    # on a pixel centre, so along the axis of the smaller spacing every node does.
    origin = (float(margin + round(0.5 * du / px)), float(margin + round(0.5 * dv / px)))
    height = math.ceil(origin[0] + (rows - 0.5) * du / px + 0.5 - 1e-9) + margin
    width = math.ceil(origin[1] + (cols - 0.5) * dv / px + 0.5 - 1e-9) + margin
    u00, v00 = float(truth.u[0, 0]), float(truth.v[0, 0])
    uc, vc = u00 + 0.5 * (rows - 1) * du, v00 + 0.5 * (cols - 1) * dv

    if not fp.max_shift < 0.5 * min(du, dv):
        raise ValueError(f"max_shift must be a sub-cell shift, below half the smaller grid spacing "
                         f"{0.5 * min(du, dv):.6g} m, got {fp.max_shift} m")
    shift = rng.uniform(-fp.max_shift, fp.max_shift, 2)
    theta = math.radians(rng.uniform(-fp.max_rotation_deg, fp.max_rotation_deg))

    # Film point x_f = centre + Rot(θ)(x − centre) + shift, so the flank point under pixel (r, c) is
    # x = centre + Rot(−θ)(x_f − centre − shift): an affine lattice in (r, c).
    ct, st = math.cos(theta), math.sin(theta)
    # d0 = x_f(pixel (0, 0)) − centre − shift
    d0 = np.array([u00 - origin[0] * px - uc - shift[0], v00 - origin[1] * px - vc - shift[1]])
    rot = np.array([[ct, st], [-st, ct]])  # Rot(−θ)
    x0 = np.array([uc, vc]) + rot @ d0
    row_step, col_step = rot @ np.array([px, 0.0]), rot @ np.array([0.0, px])
    p = truth.pressure_on_lattice(joint, flank, tuple(x0), tuple(row_step), tuple(col_step), (height, width))
    r, c = np.arange(height)[:, None], np.arange(width)[None, :]
    u_t, v_t = x0[0] + r * row_step[0] + c * col_step[0], x0[1] + r * row_step[1] + c * col_step[1]
    inside = (np.abs(u_t - uc) <= 0.5 * rows * du) & (np.abs(v_t - vc) <= 0.5 * cols * dv)
    p = np.where(inside, p, 0.0)

    g = fp.gray(p) + fp.grain * rng.standard_normal(p.shape)
    if fp.blur > 0:
        g = gaussian_filter(g, fp.blur, mode="nearest")
    image = np.clip(np.rint(g), 0, 255).astype(np.uint8)
    meta = FilmMeta(
        joint=int(joint), flank=flank, grid=(rows, cols), spacing=(du, dv), pixel_size=px, origin=origin,
        node_origin=(u00, v00), contact_level=float(fp.gray(thr)), white=fp.white, threshold_pressure=thr,
        p_sat=fp.p_sat, shift=(float(shift[0]), float(shift[1])), rotation=theta,
    )
    return image, meta


def write_film(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write a film image as an 8-bit grayscale PNG, atomically.

    Parameters
    ----------
    path : str or path-like
        Target file (its folder is created if needed).
    image : ndarray of uint8, shape (height, width)

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    image = np.asarray(image)
    if image.ndim != 2 or image.dtype != np.uint8:
        raise ValueError(f"a film image must be a 2-D uint8 array, got shape {image.shape} and dtype {image.dtype}")
    with atomic_path(path) as tmp:
        # The temporary name ends in .tmp, so the format is given, not inferred from the suffix.
        Image.fromarray(image).save(tmp, format="PNG")
    return Path(path)
