"""The full-assembly EMA judged against a virtual campaign's truth (issue 31's coverage, shapes and calibration).

``bladetwin lab simulate`` writes the full assembly's visible modes into ``truth/truth.json`` (frequencies) and
``truth/assembly_modes.npz`` (exact shapes at the test's outputs). :func:`assembly_scores` compares an EMA
model with them: the one-to-one pairing within 0.05 % (Hungarian, :func:`ema.mac.pair_by_frequency`), the
paired shapes' MAC, the EMA modes far from every true mode, and how often the truth lies within ± 2 standard
deviations. Nothing here feeds a fit: the scores only judge one.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ema.mac import mac_paired, pair_by_frequency
from ema.modal import ModalModel

__all__ = ["AssemblyTruth", "load_assembly_truth", "assembly_scores", "ONE_TO_ONE_RTOL"]

#: Relative frequency window of a one-to-one pair (issue 31: 0.05 %), and of a mode "near" a true one (1 %).
ONE_TO_ONE_RTOL, FAR_RTOL = 5e-4, 0.01


@dataclass(frozen=True)
class AssemblyTruth:
    """The full assembly's visible modes.

    Attributes
    ----------
    frequencies_hz : ndarray of float64, shape (n_visible,)
    all_frequencies_hz : ndarray of float64, shape (n_all,)
        Every true mode in the test's band, the ones too weak for the rig's visibility rule included.
    shapes : ndarray of float64, shape (n_outputs, n_visible) or None
        Exact shapes at ``outputs`` (None: a campaign written before the shapes were stored).
    blade_energy : ndarray of float64, shape (n_visible,) or None
        The blades' share of each mode's kinetic energy (below 0.5: a disk-dominated mode).
    outputs : tuple of (node, direction)
    """

    frequencies_hz: np.ndarray
    all_frequencies_hz: np.ndarray
    shapes: np.ndarray | None = None
    blade_energy: np.ndarray | None = None
    outputs: tuple[tuple[int, int], ...] = ()


def load_assembly_truth(truth_dir: Path | None) -> AssemblyTruth | None:
    """The truth of a virtual campaign's full assembly, or None where the folder has none."""
    if truth_dir is None or not (Path(truth_dir) / "truth.json").is_file():
        return None
    doc = json.loads((Path(truth_dir) / "truth.json").read_text())
    visible = doc.get("frequencies_hz", {}).get("assembly")
    if not visible:
        return None
    f = np.asarray(visible, dtype=np.float64)
    every = np.asarray(doc.get("all_frequencies_hz", {}).get("assembly") or visible, dtype=np.float64)
    path = Path(truth_dir) / "assembly_modes.npz"
    if not path.is_file():
        return AssemblyTruth(f, every)
    try:
        with np.load(path, allow_pickle=False) as z:
            shapes, energy, outputs = (np.asarray(z[k], dtype=np.float64) for k in ("shapes", "blade_energy",
                                                                                      "outputs"))
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{path}: unreadable truth file ({exc})") from None
    if shapes.shape != (outputs.shape[0], f.size) or energy.shape != f.shape:
        raise ValueError(f"{path}: shapes {shapes.shape}, blade_energy {energy.shape} do not fit "
                         f"{f.size} visible modes and {outputs.shape[0]} outputs")
    return AssemblyTruth(f, every, shapes, energy, tuple((int(n), int(d)) for n, d in outputs))


def assembly_scores(model: ModalModel, truth: AssemblyTruth) -> dict:
    """Scores of an EMA model of the full assembly against its truth.

    Returns
    -------
    dict
        ``n_modes``, ``n_visible``, ``n_within_0p05pct`` and ``one_to_one_within_0p05pct`` (a fraction of the
        visible modes), ``n_more_than_1pct_off`` (EMA modes more than 1 % from every true mode in the band, the
        invisible ones included: a weak true mode found is no error),
        ``within_2sd`` (share of the modes paired within 1 % whose truth lies within ± 2 standard deviations),
        and where the truth has shapes ``mean_shape_mac``, ``min_shape_mac`` and ``mean_shape_mac_disk``
        (the pairs within 0.05 %; the last over the disk-dominated ones, None if there are none).
    """
    f, ft = model.frequencies_hz, truth.frequencies_hz
    rows, cols = pair_by_frequency(f, ft, ONE_TO_ONE_RTOL)
    fa = truth.all_frequencies_hz
    far = int(sum(np.min(np.abs(x - fa) / fa) > FAR_RTOL for x in f)) if fa.size else int(f.size)
    a, b = pair_by_frequency(f, ft, FAR_RTOL)
    sd = model.frequency_std_hz[a] if model.frequency_std_hz is not None else np.full(a.size, np.nan)
    # a zero or missing standard deviation covers no error: such a mode counts as outside ± 2 σ
    ok = np.isfinite(sd) & (sd > 0)
    z = np.full(a.size, np.inf)
    z[ok] = np.abs(f[a] - ft[b])[ok] / sd[ok]
    out = {"n_modes": int(model.n_modes), "n_visible": int(ft.size), "n_within_0p05pct": int(rows.size),
           "one_to_one_within_0p05pct": rows.size / ft.size if ft.size else None,
           "n_more_than_1pct_off": far, "within_2sd": float(np.mean(z <= 2)) if z.size else None}
    if truth.shapes is not None and rows.size:
        index = {dof: k for k, dof in enumerate(model.outputs)}
        common = [(index[d], k) for k, d in enumerate(truth.outputs) if d in index]
        if common:
            mo, to = (np.array(x) for x in zip(*common, strict=True))
            m = mac_paired(model.shapes[mo][:, rows].T, truth.shapes[to][:, cols].T)
            disk = truth.blade_energy[cols] < 0.5
            out |= {"mean_shape_mac": float(np.mean(m)), "min_shape_mac": float(np.min(m)),
                    "mean_shape_mac_disk": float(np.mean(m[disk])) if disk.any() else None}
    return out
