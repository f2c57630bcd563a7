"""Campaign tables for the back end: blade mistuning deltas (Eq. 37), disk nodal diameters, joint frequencies."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import EMAError
from .fileio import atomic_path
from .mac import pair_modes
from .modal import ModalModel

__all__ = [
    "track_modes",
    "frequency_table",
    "blade_deltas",
    "joint_frequencies",
    "nodal_diameters",
    "nodal_diameter_purity",
    "disk_modes",
    "write_table",
]


def track_modes(
    models: Mapping[str, ModalModel], reference: str | None = None, freq_window: float = 0.1, mac_min: float = 0.6
) -> pd.DataFrame:
    """Match modes across specimens by MAC and frequency (Hungarian pairing with a reference), not by index.

    Parameters
    ----------
    models : mapping name -> ModalModel
        One model per specimen (blade, joint ...), shapes on comparable DOFs.
    reference : str, optional
        Specimen whose modes define the columns; default the first.
    freq_window, mac_min : float
        Pairing window and MAC threshold (see :func:`ema.mac.pair_modes`).

    Returns
    -------
    DataFrame
        Index: specimen names; columns ``M1..Mn`` (reference modes by ascending frequency); values: index
        of the matched mode in that specimen's model, -1 when unmatched.
    """
    names = list(models)
    if not names:
        raise EMAError("track_modes: no models given")
    ref = names[0] if reference is None else reference
    if ref not in models:
        raise EMAError(f"reference {ref!r} not among {names}")
    ref_model = models[ref].sorted()
    cols = [f"M{k + 1}" for k in range(ref_model.n_modes)]
    table = pd.DataFrame(-1, index=pd.Index(names, name="specimen"), columns=cols, dtype=int)
    for name in names:
        model = models[name]
        if name == ref:
            order = np.argsort(model.frequencies_hz, kind="stable")
            table.loc[name] = order
            continue
        pairing = pair_modes(ref_model, model, freq_window=freq_window, mac_min=mac_min)
        for a, b in pairing.pairs:
            table.loc[name, cols[a]] = int(b)
    return table


def frequency_table(models: Mapping[str, ModalModel], **kwargs) -> pd.DataFrame:
    """Natural frequencies (Hz) of tracked modes, specimen x mode; NaN when unmatched (see :func:`track_modes`)."""
    idx = track_modes(models, **kwargs)
    out = pd.DataFrame(np.nan, index=idx.index, columns=idx.columns, dtype=float)
    for name in idx.index:
        f = models[name].frequencies_hz
        for col in idx.columns:
            k = int(idx.loc[name, col])
            if k >= 0:
                out.loc[name, col] = f[k]
    return out


def blade_deltas(models: Mapping[str, ModalModel], **kwargs) -> pd.DataFrame:
    """Blade mistuning parameters in %, blade x mode (paper Eq. 37).

    ``delta_i^(j) = (omega_i^(j)^2 - <omega_i^2>) / <omega_i^2> * 100``, with ``<.>`` the mean over the
    blades where mode i was matched. Modes are tracked across blades by MAC and frequency.

    Parameters
    ----------
    models : mapping blade name -> ModalModel
        Free-free blade models on the same measurement DOFs.
    **kwargs
        Passed to :func:`track_modes`.

    Returns
    -------
    DataFrame
        Index ``blade``, columns ``M1..Mn``, values in %.
    """
    f = frequency_table(models, **kwargs)
    w2 = f**2
    mean = w2.mean(axis=0, skipna=True)
    out = (w2 - mean) / mean * 100.0
    out.index.name = "blade"
    return out


def joint_frequencies(models: Mapping[str, ModalModel], **kwargs) -> pd.DataFrame:
    """Natural frequencies (Hz), joint x mode, of the disk-one-blade assemblies, modes tracked by MAC."""
    out = frequency_table(models, **kwargs)
    out.index.name = "joint"
    return out


def nodal_diameters(shapes: np.ndarray) -> np.ndarray:
    """Nodal diameter of disk modes from one out-of-plane point per sector (spatial DFT over the sectors).

    Parameters
    ----------
    shapes : ndarray, shape (n_sectors, n_modes) or (n_sectors,)
        Out-of-plane shape values at equally spaced points, in angular order (real or complex).

    Returns
    -------
    ndarray of int, shape (n_modes,)
        Harmonic 0..n_sectors//2 with the largest energy (harmonics k and N - k folded together). The
        fraction of the energy in that harmonic is :func:`nodal_diameter_purity`.

    Raises
    ------
    EMAError
        Fewer than two sector points.
    """
    return _harmonics(shapes)[0]


def nodal_diameter_purity(shapes: np.ndarray) -> np.ndarray:
    """Fraction of each disk mode's energy in its nodal diameter (see :func:`nodal_diameters`).

    Parameters
    ----------
    shapes : ndarray, shape (n_sectors, n_modes) or (n_sectors,)

    Returns
    -------
    ndarray, shape (n_modes,)
        In (0, 1]; 1 for a pure ``cos(n theta + psi)`` pattern.
    """
    return _harmonics(shapes)[1]


def _harmonics(shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nodal diameter (int) and purity of each column, shapes (n_modes,) both."""
    phi = np.asarray(shapes, dtype=np.complex128)
    if phi.ndim == 1:
        phi = phi[:, None]
    N = phi.shape[0]
    if phi.ndim != 2 or N < 2:
        raise EMAError(f"nodal_diameters: shapes of shape {np.shape(shapes)}; expected (n_sectors >= 2, n_modes)")
    # real and imaginary parts are two standing waves; sum their harmonic energies
    energy = np.abs(np.fft.fft(phi.real, axis=0)) ** 2 + np.abs(np.fft.fft(phi.imag, axis=0)) ** 2
    half = N // 2
    folded = np.zeros((half + 1, phi.shape[1]))
    for k in range(N):
        folded[min(k, N - k)] += energy[k]
    nd = np.argmax(folded, axis=0).astype(int)
    total = folded.sum(axis=0)
    purity = folded[nd, np.arange(phi.shape[1])] / np.where(total > 0, total, 1.0)
    return nd, purity


def disk_modes(model: ModalModel, sector_dofs: list[tuple[int, int]] | None = None) -> pd.DataFrame:
    """Disk modes with nodal diameters.

    Parameters
    ----------
    model : ModalModel
        Identified disk model.
    sector_dofs : list of (node, direction), optional
        The out-of-plane DOF of each sector in angular order; default the model's DOFs sorted by node.

    Returns
    -------
    DataFrame
        Columns ``frequency_hz``, ``damping_ratio``, ``nodal_diameter``, ``nd_purity``; index ``mode`` (1..).
    """
    if sector_dofs is None:
        rows = np.argsort([n for n, _ in model.dofs], kind="stable")
    else:
        lookup = {d: k for k, d in enumerate(model.dofs)}
        missing = [d for d in sector_dofs if tuple(d) not in lookup]
        if missing:
            raise EMAError(f"sector DOFs {missing} not in the model's DOFs")
        rows = np.array([lookup[tuple(d)] for d in sector_dofs])
    nd, purity = _harmonics(model.shapes[rows])
    return pd.DataFrame(
        {
            "frequency_hz": model.frequencies_hz,
            "damping_ratio": model.damping_ratio,
            "nodal_diameter": nd,
            "nd_purity": purity,
        },
        index=pd.Index(np.arange(1, model.n_modes + 1), name="mode"),
    )


def write_table(table: pd.DataFrame, path: str | os.PathLike, float_format: str = "%.6g") -> Path:
    """Write a table to CSV atomically (temporary file in the same folder, then ``os.replace``)."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        table.to_csv(fh, float_format=float_format)
    return path
