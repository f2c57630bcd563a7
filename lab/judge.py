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
from scipy.special import erf

from ema.fit_noise import noise_model
from ema.frf import FRF_FORMS, FRFSet
from ema.mac import mac_paired, pair_by_frequency
from ema.modal import ModalModel
from lab.rig import RigSetup

__all__ = ["AssemblyTruth", "load_assembly_truth", "assembly_scores", "shape_mac_bound", "frequency_bound",
           "coverage_bound", "ONE_TO_ONE_RTOL"]

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
    damping_ratio : ndarray of float64, shape (n_visible,) or None
        The visible modes' damping ratios as the test saw them (the structure's plus its exponential window's).
    all_apparent_hz : ndarray of float64, shape (n_in_band,) or None
        The natural frequencies the test's data hold, ``all_frequencies_hz`` moved by its exponential window
        (None: no window). The ± 2 σ score measures the EMA against these.
    """

    frequencies_hz: np.ndarray
    all_frequencies_hz: np.ndarray
    shapes: np.ndarray | None = None
    blade_energy: np.ndarray | None = None
    outputs: tuple[tuple[int, int], ...] = ()
    damping_ratio: np.ndarray | None = None
    all_apparent_hz: np.ndarray | None = None


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
    zeta = doc.get("damping_ratios", {}).get("assembly")
    zeta = np.asarray(zeta, dtype=np.float64) if zeta is not None and len(zeta) == f.size else None
    window = doc.get("window_damping", {}).get("assembly")
    if zeta is not None and window is not None and len(window) == f.size:
        zeta = zeta + np.asarray(window, dtype=np.float64)  # what the test saw: its exponential window's too
    apparent = doc.get("all_apparent_frequencies_hz", {}).get("assembly")
    apparent = np.asarray(apparent, dtype=np.float64) if apparent is not None and len(apparent) == every.size \
        else None
    path = Path(truth_dir) / "assembly_modes.npz"
    if not path.is_file():
        return AssemblyTruth(f, every, damping_ratio=zeta, all_apparent_hz=apparent)
    try:
        with np.load(path, allow_pickle=False) as z:
            shapes, energy, outputs = (np.asarray(z[k], dtype=np.float64) for k in ("shapes", "blade_energy",
                                                                                      "outputs"))
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{path}: unreadable truth file ({exc})") from None
    if shapes.shape != (outputs.shape[0], f.size) or energy.shape != f.shape:
        raise ValueError(f"{path}: shapes {shapes.shape}, blade_energy {energy.shape} do not fit "
                         f"{f.size} visible modes and {outputs.shape[0]} outputs")
    return AssemblyTruth(f, every, shapes, energy, tuple((int(n), int(d)) for n, d in outputs), zeta, apparent)


def assembly_scores(model: ModalModel, truth: AssemblyTruth) -> dict:
    """Scores of an EMA model of the full assembly against its truth.

    Returns
    -------
    dict
        ``n_modes``, ``n_visible``, ``n_within_0p05pct`` and ``one_to_one_within_0p05pct`` (a fraction of the
        visible modes), ``n_more_than_1pct_off`` (EMA modes more than 1 % from every true mode in the band, the
        invisible ones included: a weak true mode found is no error),
        ``within_2sd`` (share of the EMA modes within 1 % of a true mode whose nearest true mode lies within
        ± 2 standard deviations),
        and where the truth has shapes ``mean_shape_mac``, ``min_shape_mac`` and ``mean_shape_mac_disk``
        (the pairs within 0.05 %; the last over the disk-dominated ones, None if there are none).
    """
    f, ft = model.frequencies_hz, truth.frequencies_hz
    rows, cols = pair_by_frequency(f, ft, ONE_TO_ONE_RTOL)
    # Each found mode against the true mode it estimates: the nearest one (the invisible ones included); more
    # than 1 % from it, the mode is far. Not a one-to-one pairing: with one duplicate and one missed mode in a
    # family, a maximum one-to-one pairing shifts a chain of neighbours onto the wrong truths (seed 11: z of 23
    # and 25 for modes 0.004 and 0.044 Hz from their own true mode).
    every = truth.all_frequencies_hz if truth.all_frequencies_hz.size else ft
    held = truth.all_apparent_hz if truth.all_apparent_hz is not None and every is truth.all_frequencies_hz else every
    if f.size and every.size:
        k = np.argmin(np.abs(f[:, None] - every[None, :]), axis=1)
        nearest, pole = every[k], held[k]
        near = np.abs(f - nearest) <= FAR_RTOL * nearest
    else:
        nearest, pole, near = np.zeros(f.size), np.zeros(f.size), np.zeros(f.size, bool)
    far, a = int(np.count_nonzero(~near)), np.flatnonzero(near)
    sd = model.frequency_std_hz[a] if model.frequency_std_hz is not None else np.full(a.size, np.nan)
    # a zero or missing standard deviation covers no error: such a mode counts as outside ± 2 σ
    ok = np.isfinite(sd) & (sd > 0)
    z = np.full(a.size, np.inf)
    # against the pole the data hold (a window moves it by about 1e-6, a few σ here), not the structure's
    z[ok] = np.abs(f[a] - pole[a])[ok] / sd[ok]
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


def shape_mac_bound(truth: AssemblyTruth, frf: FRFSet, multiplicative: float = RigSetup.multiplicative_noise,
                    additive: float = RigSetup.additive_noise, threshold: float | None = None,
                    n_draws: int = 200, joint: bool = False) -> np.ndarray:
    """The shape MAC that an estimate limited only by the test's noise reaches, per visible mode.

    Each output's shape entry is estimated as if everything else were known (the pole, the other modes, the
    references' entries): the least-squares estimate over every reference and line, weighted by the rig's
    noise, whose variance is the Cramér–Rao bound ``1 / Σ_i Σ_ω |φ_i g(ω)|² / v_oi(ω)`` with
    ``g = (jω)^k / (ω_r² − ω² + 2 j ζ_r ω_r ω)`` and ``v_oi = (additive · RMS_oi)² + (multiplicative · |H_oi|)²``
    (the virtual rig's model, :func:`lab.rig.measure`; ``H``: the measured FRFs). Returned is the mean MAC of
    such estimates against the exact shape over ``n_draws`` draws (fixed seed). With ``threshold`` the entries
    below that many standard deviations are zeroed first (an estimator that reports unmeasurable entries as 0).
    No unbiased estimator does better than the first figure on average: a real one must also find the poles
    and separate the modes. A mode no reference excites scores 0.

    With ``joint``, each output's entries of all the modes of a cluster (neighbours within 10 ζ f) are estimated
    together, their covariance the inverse of their joint Fisher information
    ``Σ_i Σ_ω conj(φ_ir g_r) φ_is g_s / v_oi``: the poles and the references' entries still known, the
    neighbours' shapes not. For modes a small fraction of a bandwidth apart this is far below the first figure
    (design §8.63).

    Parameters
    ----------
    truth : AssemblyTruth
        With shapes and damping ratios.
    frf : FRFSet
        The full-assembly test: its references must be among the truth's outputs.

    Returns
    -------
    ndarray of float64, shape (n_visible,)
    """
    if truth.shapes is None or truth.damping_ratio is None:
        raise ValueError("shape_mac_bound: the truth has no shapes or damping ratios")
    phi_o, phi_i, lines = _test_shapes(truth, frf, "shape_mac_bound")   # (n_out | n_in, n_visible)
    H = frf.H[:, :, lines]
    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=2, keepdims=True))
    v = np.maximum((additive * rms) ** 2 + (multiplicative * np.abs(H)) ** 2, np.finfo(float).tiny)
    w = 2 * np.pi * frf.freq_hz[lines]
    g = _kernels(2 * np.pi * truth.frequencies_hz, truth.damping_ratio, w, (1j * w) ** FRF_FORMS[frf.form])[0]
    rng = np.random.default_rng(0)
    if joint:
        return _joint_mac_bound(phi_o, phi_i, g, v, rng, n_draws, threshold, truth.frequencies_hz,
                                truth.damping_ratio, frf.freq_hz[lines])
    g2 = np.abs(g) ** 2                                                      # (n_visible, n_lines)
    out = np.zeros(truth.frequencies_hz.size)
    for c in range(out.size):
        info = np.einsum("i,oif->o", phi_i[:, c] ** 2, g2[c][None, None, :] / v)
        if not np.all(info > 0):
            continue                      # no reference excites the mode: no estimate, MAC 0
        sd = 1.0 / np.sqrt(info)
        e = sd * (rng.standard_normal((n_draws, sd.size)) + 1j * rng.standard_normal((n_draws, sd.size)))
        est = phi_o[:, c] + e / np.sqrt(2)
        if threshold is not None:
            est = np.where(np.abs(est) > threshold * sd, est, 0.0)
        out[c] = _mean_mac(est[:, :, None], phi_o[:, c:c + 1])[0]
    return out


def _mean_mac(est: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Mean MAC over draws of estimated shapes ``est`` (n_draws, n_out, K) against exact ones ``phi`` (n_out, K);
    0 for an all-zero draw. Shape (K,)."""
    num = np.abs(np.einsum("dok,ok->dk", est, phi)) ** 2
    den = np.sum(np.abs(est) ** 2, axis=1) * np.sum(phi**2, axis=0)
    return np.mean(np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0), axis=0)


def _joint_mac_bound(phi_o, phi_i, g, v, rng, n_draws, threshold, f, zeta, freq) -> np.ndarray:
    """:func:`shape_mac_bound` with each cluster's entries at an output drawn jointly (``joint=True``).

    Clusters split where neighbours lie more than 10 ζ f apart (:func:`_clusters`), whose shapes barely interact;
    each cluster's information is summed over its lines within 40 ζ f of it (the rest holds about 2 % of a mode's
    information). Both keep a 48-blade test's bound to seconds (all lines and 40 ζ f clusters took minutes)."""
    out = np.zeros(phi_o.shape[1])
    for idx in _clusters(f, zeta, 10.0):
        reach = 40.0 * np.max(zeta[idx] * f[idx])
        near = (freq >= f[idx].min() - reach) & (freq <= f[idx].max() + reach)
        A = phi_i[:, idx, None] * g[None, idx][:, :, near]                    # (n_in, K, n_lines near)
        est = np.repeat(phi_o[None, :, idx].astype(complex), n_draws, axis=0)  # (n_draws, n_out, K)
        seen = np.ones(idx.size, bool)
        for o in range(phi_o.shape[0]):
            W = (A / np.sqrt(v[o][:, near])[:, None, :]).transpose(1, 0, 2).reshape(idx.size, -1)
            info = W.conj() @ W.T                                             # Fisher information, (K, K)
            seen &= np.real(np.diag(info)) > 0
            lam, U = np.linalg.eigh(info)
            # the covariance's square root from the information's eigenvectors; a direction the references do not
            # excite gets a huge variance (its modes' estimates are noise there), not none
            root = U / np.sqrt(np.maximum(lam, max(lam.max(initial=0.0), np.finfo(float).tiny) * 1e-14))
            z = rng.standard_normal((n_draws, idx.size)) + 1j * rng.standard_normal((n_draws, idx.size))
            e = (z / np.sqrt(2)) @ root.T
            est[:, o] += e
            if threshold is not None:
                sd = np.sqrt(np.sum(np.abs(root) ** 2, axis=1))
                est[:, o] = np.where(np.abs(est[:, o]) > threshold * sd, est[:, o], 0.0)
        out[idx] = np.where(seen, _mean_mac(est, phi_o[:, idx]), 0.0)
    return out


def frequency_bound(truth: AssemblyTruth, frf: FRFSet, multiplicative: float | None = None,
                    additive: float | None = None, span: float = 40.0) -> np.ndarray:
    """The Cramér–Rao bound of each visible mode's natural frequency: the smallest standard deviation (Hz) that an
    unbiased estimate from this test can have.

    The model is the truth's visible modes, ``H_oi = Σ_r φ_or φ_ir g_r(ω)`` with ``g_r`` as in
    :func:`shape_mac_bound`; its unknowns are each mode's ω_r, ζ_r and shape at every output, the references'
    entries taken as known (so the bound is, if anything, optimistic). The noise is circular complex Gaussian with
    variance ``v_oi(ω) = (additive · RMS_oi)² + (multiplicative · |H_oi|)²`` where both shares are given (the
    virtual rig's frequency-domain model, :func:`lab.rig.measure`), else the two-part model that
    :func:`ema.fit_noise.noise_model` fits to the residual of the truth's modes (what a time-domain hammer test
    really adds, plus the modes the truth leaves out). Modes are bounded cluster by cluster: a gap of more than
    ``span`` half-power bandwidths splits them, and each cluster takes the lines within ``span`` bandwidths of it.
    The frequency's variance is the diagonal of the inverse of the Fisher information of (ω, ζ) after the shapes
    are eliminated (its Schur complement), output by output.

    Parameters
    ----------
    truth : AssemblyTruth
        With shapes and damping ratios.
    frf : FRFSet
        The full-assembly test: its outputs and references must be among the truth's outputs.
    multiplicative, additive : float, optional
        The noise shares (:class:`lab.rig.RigSetup`); both or neither.
    span : float
        Half-power bandwidths that split two clusters and bound each cluster's lines.

    Returns
    -------
    ndarray of float64, shape (n_visible,)
        Hz; infinite for a mode that no reference excites.
    """
    if truth.shapes is None or truth.damping_ratio is None:
        raise ValueError("frequency_bound: the truth has no shapes or damping ratios")
    phi_o, phi_i, lines = _test_shapes(truth, frf, "frequency_bound")
    H = frf.H[:, :, lines]
    w = 2 * np.pi * frf.freq_hz[lines]
    c = (1j * w) ** FRF_FORMS[frf.form]
    f, zeta = truth.frequencies_hz, truth.damping_ratio
    wr = 2 * np.pi * f
    model = np.einsum("or,ir,rl->oil", phi_o, phi_i, _kernels(wr, zeta, w, c)[0])
    if multiplicative is not None and additive is not None:
        rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=2, keepdims=True))
        v = (additive * rms) ** 2 + (multiplicative * np.abs(H)) ** 2
    else:
        floor, share = noise_model(np.abs(H - model) ** 2, np.abs(model) ** 2, axis=2)
        v = floor + share * np.abs(model) ** 2
    weight = 2.0 / np.maximum(v, np.finfo(float).tiny)       # Fisher: 2 Re(∂Hᴴ ∂H) / v per complex value
    sd = np.full(f.size, np.inf)
    for group in _clusters(f, zeta, span):
        reach = span * float(np.max(zeta[group] * f[group]))
        near = (w >= 2 * np.pi * (f[group].min() - reach)) & (w <= 2 * np.pi * (f[group].max() + reach))
        sd[group] = _cluster_bound(wr[group], zeta[group], w[near], c[near], phi_o[:, group], phi_i[:, group],
                                   weight[:, :, near])
    return sd


def coverage_bound(truth: AssemblyTruth, sd_hz: np.ndarray) -> float:
    """The share of the visible modes that an efficient estimate with standard deviations ``sd_hz``
    (:func:`frequency_bound`) puts within :data:`ONE_TO_ONE_RTOL` of the truth, on average: the ceiling of
    :func:`assembly_scores`' ``one_to_one_within_0p05pct`` that the test's information sets."""
    tol = ONE_TO_ONE_RTOL * truth.frequencies_hz
    with np.errstate(divide="ignore"):
        z = np.where(np.isfinite(sd_hz) & (sd_hz > 0), tol / (np.sqrt(2) * sd_hz), 0.0)
    return float(np.mean(erf(z))) if z.size else float("nan")


def _test_shapes(truth: AssemblyTruth, frf: FRFSet, who: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The truth's shapes at the test's outputs and references, and the test's usable lines (a boolean mask)."""
    index = {dof: k for k, dof in enumerate(truth.outputs)}
    missing = [d for d in (*frf.outputs, *frf.inputs) if tuple(d) not in index]
    if missing:
        raise ValueError(f"{who}: DOFs {missing[:3]} of the test are not among the truth's outputs")
    phi_o = truth.shapes[[index[tuple(d)] for d in frf.outputs]]
    phi_i = truth.shapes[[index[tuple(d)] for d in frf.inputs]]
    return phi_o, phi_i, frf.valid_lines() & (frf.freq_hz > 0)


def _kernels(wr: np.ndarray, zeta: np.ndarray, w: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each mode's FRF kernel ``g_r(ω) = c(ω) / (ω_r² − ω² + 2 j ζ_r ω_r ω)`` and its denominator, each shape
    (n_modes, n_lines); ``c = (jω)^k`` of the FRF form."""
    den = wr[:, None] ** 2 - w**2 + 2j * (zeta * wr)[:, None] * w
    return c / den, den


def _clusters(f: np.ndarray, zeta: np.ndarray, span: float) -> list[np.ndarray]:
    """Indices of the modes in groups, split where the gap exceeds ``span`` half-power bandwidths of either side."""
    order = np.argsort(f)
    groups = [[order[0]]] if f.size else []
    for a, b in zip(order[:-1], order[1:], strict=True):
        if f[b] - f[a] > span * max(zeta[a] * f[a], zeta[b] * f[b]):
            groups.append([b])
        else:
            groups[-1].append(b)
    return [np.array(g) for g in groups]


def _cluster_bound(wr, zeta, w, c, phi_o, phi_i, weight) -> np.ndarray:
    """Frequency bounds (Hz) of one cluster's K modes: Fisher information of (ω, ζ) and of each output's shape
    entries, the shapes eliminated output by output (their blocks couple only through the poles)."""
    K, (n_out, n_in) = wr.size, (phi_o.shape[0], phi_i.shape[0])
    g, den = _kernels(wr, zeta, w, c)                                        # (K, L)
    dg = np.vstack([-c * (2 * wr[:, None] + 2j * zeta[:, None] * w) / den**2,  # ∂g/∂ω_r
                    -c * (2j * wr[:, None] * w) / den**2])                    # ∂g/∂ζ_r
    poles = np.zeros((2 * K, 2 * K))
    schur = np.zeros((2 * K, 2 * K))
    for o in range(n_out):
        cross, shapes = np.zeros((2 * K, K)), np.zeros((K, K))
        for i in range(n_in):
            a = np.tile(phi_o[o] * phi_i[i], 2)
            wd = dg.conj() * weight[o, i]
            poles += np.real(np.outer(a, a) * (wd @ dg.T))
            cross += np.real(a[:, None] * (wd @ g.T) * phi_i[i][None, :])
            shapes += np.real(np.outer(phi_i[i], phi_i[i]) * ((g.conj() * weight[o, i]) @ g.T))
        schur += cross @ np.linalg.pinv(shapes, rcond=1e-12) @ cross.T
    info = poles - schur
    try:
        var = np.diag(np.linalg.inv(info))[:K]
    except np.linalg.LinAlgError:
        return np.full(K, np.inf)
    return np.where(var > 0, np.sqrt(np.abs(var)), np.inf) / (2 * np.pi)
