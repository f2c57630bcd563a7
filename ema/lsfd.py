"""Least-squares frequency-domain (LSFD) estimation of residues, mode shapes and synthesised FRFs.

Receptance model of each FRF (viscous damping, complex residues, real residual terms)::

    H(omega) = sum_r [ A_r / (j omega - lambda_r) + conj(A_r) / (j omega - conj(lambda_r)) ]
               + L / (j omega)^2 + U

and the mobility / accelerance model is that times ``(j omega)^k``. With the poles fixed the model is
linear in Re A_r, Im A_r, L and U; all FRFs share one basis and are solved together. The poles are refined
on the same model by :func:`ema.varpro.refine_poles`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.linalg import solve_triangular

from .fit_noise import band_floor
from .frf import FRF_FORMS, FRFSet
from .modal import ModalModel, modal_from_pole
from .poles import band_data

__all__ = ["lsfd", "local_windows", "local_residues", "modal_model", "synthesize", "fit_quality", "dominance",
           "modal_basis", "band_lines", "column_sines", "nearly_dependent", "triangular_solve", "half_widths",
           "shapes_from_residues", "LOCAL_HALF_WIDTHS", "LOCAL_MIN_LINES"]


def modal_basis(poles: np.ndarray, freq_hz: np.ndarray, form: str, residuals: bool) -> np.ndarray:
    """Real-coefficient basis, complex values, shape (n_freq, 2 n_modes [+ 2])."""
    jw = 1j * 2 * np.pi * freq_hz[:, None]
    a = 1.0 / (jw - poles[None, :])
    b = 1.0 / (jw - poles.conj()[None, :])
    cols = [a + b, 1j * (a - b)]
    if residuals:
        cols += [1.0 / jw**2, np.ones_like(jw)]
    B = np.hstack(cols)
    k = FRF_FORMS[form]
    if k:
        B = B * jw**k
    return B


def band_lines(frf: FRFSet, band, per: str, residuals: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lines of the band (Hz, shape (n_f,)), the scaled FRFs on them as columns, shape (n_f, n_outputs·n_inputs),
    and the factor each column was multiplied by, shape (n_outputs·n_inputs,) (see :func:`ema.poles.band_data`).

    With residual terms the 0 Hz line is dropped (the lower residual ~ 1/ω² is singular there).
    """
    data = band_data(frf, band, per=per)
    f = data.freq_hz
    Y = data.H.reshape(frf.n_outputs * frf.n_inputs, -1).T
    scale = np.broadcast_to(
        data.scale.reshape(frf.n_outputs, -1), (frf.n_outputs, frf.n_inputs)
    ).reshape(-1)
    if residuals:
        nz = f > 0
        f, Y = f[nz], Y[nz]
    return f, Y, scale


def _solve(B: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real least squares ``B c = Y`` for complex B (n_freq, n_c) and Y (n_freq, n_y); returns c and fit."""
    A = np.vstack([B.real, B.imag])
    rhs = np.vstack([Y.real, Y.imag])
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    # QR, not lstsq's SVD: that took 16 of a 48-blade fit's 290 s, with as many right-hand sides as FRFs
    Q, R = np.linalg.qr(A / scale)
    c = triangular_solve(R, Q.T @ rhs) / scale[:, None]
    return c, B @ c


def column_sines(R: np.ndarray) -> np.ndarray:
    """Each column's sine to the span of the columns before it, from a QR's triangular factor ``R`` (scale-free,
    unlike cond(R)); near 0 where a column nearly depends on the earlier ones. Shape (n_columns,)."""
    return np.abs(np.diag(R)) / np.maximum(np.linalg.norm(R, axis=0), np.finfo(float).tiny)


def nearly_dependent(R: np.ndarray) -> bool:
    """Does a column of a QR's factor ``R`` have a sine of at most 1e-8 to the columns before it (two equal
    poles), where back substitution and the Gram route of :mod:`ema.gram` lose the digits?"""
    return bool(column_sines(R).min(initial=1.0) <= 1e-8)


def triangular_solve(R: np.ndarray, QtY: np.ndarray) -> np.ndarray:
    """The least-squares coefficients from a QR ``A = Q R`` and ``Qᵀ Y``: back substitution, or the minimum-norm
    solution where columns nearly depend (:func:`nearly_dependent`)."""
    if nearly_dependent(R):
        return np.linalg.lstsq(R, QtY, rcond=None)[0]
    return solve_triangular(R, QtY, check_finite=False)


def lsfd(
    frf: FRFSet,
    poles: np.ndarray,
    band: tuple[float, float] | None = None,
    residuals: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residues and residual terms for given poles.

    Parameters
    ----------
    frf : FRFSet
        Measured FRFs, shape (n_outputs, n_inputs, n_freq).
    poles : ndarray of complex, shape (n_modes,)
        Continuous-time poles in rad/s (positive imaginary part).
    band : (f_lo, f_hi) in Hz, optional
        Lines used; default all finite lines (0 Hz is skipped when residuals are fitted).
    residuals : bool
        Fit the lower (``L/(j omega)^2``) and upper (``U``) residual terms.

    Returns
    -------
    residues : ndarray of complex128, shape (n_modes, n_outputs, n_inputs)
        Receptance residues ``A_r``.
    lower, upper : ndarray of complex128, shape (n_outputs, n_inputs)
        Residual terms (zeros when not fitted).
    """
    poles = np.asarray(poles, dtype=np.complex128).reshape(-1)
    c, _ = _lsfd_columns([frf], poles, band, residuals)[0]
    n = poles.size
    A = (c[:n] + 1j * c[n : 2 * n]).reshape(n, frf.n_outputs, frf.n_inputs)
    shape = (frf.n_outputs, frf.n_inputs)
    if residuals:
        lower = c[2 * n].reshape(shape).astype(np.complex128)
        upper = c[2 * n + 1].reshape(shape).astype(np.complex128)
    else:
        lower = np.zeros(shape, dtype=np.complex128)
        upper = np.zeros(shape, dtype=np.complex128)
    return A, lower, upper


def _lsfd_columns(frfs: list[FRFSet], poles: np.ndarray, band: tuple[float, float] | None, residuals: bool
                  ) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each FRF set (the same lines and form), the LSFD's real coefficients, shape (2 n_modes [+ 2],
    n_outputs·n_inputs), and each FRF's residual norm (Σ|H − Ĥ|²)^½ over the lines, shape
    (n_outputs·n_inputs,). Each FRF is its own least-squares problem; all share one basis and one solve."""
    # solved on data brought to unit size by one power of two (exact), then scaled back: residues of
    # FRFs of 1e-156 or 1e+144 would otherwise under- or overflow in the least-squares solve
    lines = [band_lines(frf, band, "scalar", residuals) for frf in frfs]
    f = lines[0][0]
    if any(not np.array_equal(x[0], f) for x in lines[1:]):
        raise ValueError("_lsfd_columns: the FRF sets do not share their lines")
    B = modal_basis(poles, f, frfs[0].form, residuals)
    Y, scale = np.hstack([x[1] for x in lines]), np.concatenate([x[2] for x in lines])
    c, fit = _solve(B, Y)
    c, norm = c / scale[None, :], np.linalg.norm(Y - fit, axis=0) / scale
    cuts = np.cumsum([x[1].shape[1] for x in lines])[:-1]
    return list(zip(np.split(c, cuts, axis=1), np.split(norm, cuts), strict=True))


#: Half-width of a mode's local window in half-power half-bandwidths (``zeta f``): the resonance down to
#: about -20 dB, where the residual terms absorb what lies outside (see :func:`local_windows`).
LOCAL_HALF_WIDTHS = 10.0
#: Least half-width of a local window, in lines: a lightly damped mode still gets enough lines around it.
LOCAL_MIN_LINES = 20


def half_widths(poles: np.ndarray, frf: FRFSet, band: tuple[float, float]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (Hz), local half-widths ``max(LOCAL_HALF_WIDTHS · ζ f, LOCAL_MIN_LINES lines)`` (Hz) of the
    poles, and the FRFs' finite lines above 0 Hz inside ``band`` that the widths count."""
    f, z = modal_from_pole(np.asarray(poles, dtype=np.complex128).reshape(-1))
    freq = frf.freq_hz
    lines = freq[frf.valid_lines() & (freq > 0) & (freq >= band[0]) & (freq <= band[1])]
    spacing = np.interp(f, lines, np.gradient(lines)) if lines.size > 1 else np.zeros_like(f)
    return f, np.maximum(LOCAL_HALF_WIDTHS * z * f, LOCAL_MIN_LINES * spacing), lines


def local_windows(
    poles: np.ndarray, frf: FRFSet, band: tuple[float, float]
) -> list[tuple[tuple[float, float], np.ndarray] | None]:
    """Each mode's local window and the poles that share it (the local fits of refinement and shapes).

    Mode r gets ``f_r ± W_r``, ``W_r = max(LOCAL_HALF_WIDTHS · zeta_r f_r, LOCAL_MIN_LINES lines)``, clipped
    to ``band``, with the modes within ``2 W_r`` as poles. A window holding fewer than ``4 n + 4`` lines for
    its n poles (too few for their residues and the residual terms) is ``None``.

    Parameters
    ----------
    poles : ndarray of complex, shape (n_modes,)
    frf : FRFSet
        Its finite lines above 0 Hz inside ``band`` are the ones the windows count.
    band : (f_lo, f_hi) in Hz

    Returns
    -------
    list of ((lo, hi), near) or None, one per mode
        ``near``: indices of the window's poles (ascending, mode r among them).
    """
    f, halves, lines = half_widths(poles, frf, band)
    out: list[tuple[tuple[float, float], np.ndarray] | None] = []
    for r in range(f.size):
        half = halves[r]
        window = (max(band[0], f[r] - half), min(band[1], f[r] + half))
        near = np.flatnonzero(np.abs(f - f[r]) <= 2.0 * half)
        enough = np.count_nonzero((lines >= window[0]) & (lines <= window[1])) >= 4 * near.size + 4
        out.append((window, near) if enough else None)
    return out


def local_residues(frf: FRFSet, poles: np.ndarray, band: tuple[float, float], residues: np.ndarray) -> np.ndarray:
    """Each mode's residues from an LSFD over its own window (:func:`local_windows`), shape (n_modes, n_o, n_i).

    Why: over a wide band every residue also absorbs the misfit of the whole band, e.g. of a cluster whose
    modes the estimator did not all find. A mode that a response point barely sees (a disk mode at a blade
    tip) then gets that misfit as its shape there, in the same pattern for every such mode. In a window of
    a few bandwidths only the nearby poles and two residual terms share the data. Each FRF is fitted twice
    there, as it is and less the whole-band fit's terms of the modes outside the window
    (:func:`_less_far_modes`), and keeps the fit with the smaller residual. Modes whose window has too few
    lines, or is refused, keep their row of ``residues`` (the whole-band fit). ``band`` (Hz) is the resolved
    data band of that fit.
    """
    poles = np.asarray(poles, dtype=np.complex128).reshape(-1)
    out = np.array(residues, dtype=np.complex128, copy=True)
    for r, item in enumerate(local_windows(poles, frf, band)):
        if item is None:
            continue
        window, near = item
        try:
            (raw, cost_raw), (less, cost_less) = _lsfd_columns(
                [frf, _less_far_modes(frf, poles, residues, near, window)], poles[near], window, True)
        except ValueError:  # a window the LSFD refuses: keep the whole-band residues
            continue
        # per FRF, the fit that explains the window better (the same unknowns either way): the far modes'
        # terms help where a strong family outside bends the data, and hurt where the whole-band fit of that
        # family is poor (a missed member)
        c = np.where(cost_less < cost_raw, less, raw)
        k, n = int(np.searchsorted(near, r)), near.size
        out[r] = (c[k] + 1j * c[n + k]).reshape(frf.n_outputs, frf.n_inputs)
    return out


def _less_far_modes(frf: FRFSet, poles: np.ndarray, residues: np.ndarray, near: np.ndarray,
                    window: tuple[float, float]) -> FRFSet:
    """The window's lines of ``frf`` less the whole-band fit's terms of the modes outside ``near``.

    Why: a strong family just outside the window (the 1190 Hz blade family beside a 1139 Hz disk pair) bends
    the data inside it more than two residual terms can follow, and the misfit lands in the weak mode's
    residues at the points where that family is large (seed 11: shape MAC 0.55 against the exact shape; with
    the far modes taken out where that fits the window better, 0.97).
    """
    sel = (frf.freq_hz >= window[0]) & (frf.freq_hz <= window[1])
    far = np.setdiff1d(np.arange(poles.size), near)
    freq = frf.freq_hz[sel]
    terms = _pole_terms(residues[far], poles[far], freq, FRF_FORMS[frf.form])
    return replace(frf, freq_hz=freq, H=frf.H[:, :, sel] - terms)


def _pole_terms(A: np.ndarray, poles: np.ndarray, freq_hz: np.ndarray, power: int) -> np.ndarray:
    """``(jω)^power Σ_r [A_r/(jω − λ_r) + conj(A_r)/(jω − conj λ_r)]``, shape (n_outputs, n_inputs, n_freq).

    ``A``: residues, shape (n_modes, n_outputs, n_inputs), receptance convention; ``poles`` in rad/s.
    """
    jw = 1j * 2 * np.pi * np.asarray(freq_hz, dtype=np.float64)
    n, n_out, n_in = A.shape
    # one matrix product over the modes (BLAS), not an einsum: on a 24-blade campaign's family windows the einsum
    # took 17 of the fit's 113 s
    kernels = np.vstack([1.0 / (jw[None, :] - poles[:, None]), 1.0 / (jw[None, :] - poles.conj()[:, None])])
    H = (np.concatenate([A, A.conj()]).reshape(2 * n, n_out * n_in).T @ kernels).reshape(n_out, n_in, jw.size)
    return H * jw**power if power else H


def shapes_from_residues(A: np.ndarray, poles: np.ndarray, frf: FRFSet,
                         noise: np.ndarray | None = None) -> tuple[np.ndarray, tuple, str]:
    """Mode shapes from residue matrices (rank-one approximation), mass-scaled when driving points exist.

    The shape of mode r is the dominant singular vector of its residue matrix ``A_r`` (n_outputs × n_inputs),
    so every reference contributes. With ``noise`` (each FRF's noise σ, shape (n_outputs, n_inputs)) it is the
    rank-one fit weighted by ``1/σ²`` instead (:func:`weighted_rank_one`): each residue is one FRF's fit, its
    error in proportion to that FRF's noise. It is then scaled to unit modal mass by a least-squares fit over all
    driving points d = (o, i) of ``A_r = phi phi^T / (2 j omega_d)``: with ``phi = c u`` and the driven
    columns ``A_r[:, i] = c^2 u u_o / (2 j omega_d)``,

        c^2 = 2 j omega_d sum_d conj(u_o) (u^H A_r[:, i]) / sum_d |u_o|^2.

    Why not the first driving point's column alone: a mode with a node at that reference (a localised
    mistuned mode on a blade far from it, or a disk mode whose nodal line runs through it) has a column of
    noise there, and its shape came out as noise although the other references saw it clearly. With one
    reference the two are the same (``phi = 2 j omega_d A_r[:, i] / sqrt(2 j omega_d A_r[o, i])``).
    The sign makes ``phi_o`` at the first driving point the principal square root of ``2 j omega_d A_r[o, i]``.
    """
    n, n_o, n_i = A.shape
    on_outputs = n_o >= n_i
    dofs = frf.outputs if on_outputs else frf.inputs
    # (row on the shape side, column on the other side) of each driving point
    drive = [(o, i) if on_outputs else (i, o)
             for o, do in enumerate(frf.outputs) for i, di in enumerate(frf.inputs) if do == di]
    rows = np.array([d[0] for d in drive], dtype=int)
    cols = np.array([d[1] for d in drive], dtype=int)
    phi = np.zeros((len(dofs), n), dtype=np.complex128)
    scaling = "mass" if drive else "unit"
    if noise is not None:
        sd = np.asarray(noise, np.float64) if on_outputs else np.asarray(noise, np.float64).T
        w = (np.min(sd) / sd) ** 2          # only the ratios matter; scaled so that none overflows
    for r in range(n):
        B = A[r] if on_outputs else A[r].T  # rows: the shape's DOFs
        u = np.linalg.svd(B)[0][:, 0] if noise is None else weighted_rank_one(B, w)
        v = None
        if drive:
            ud = u[rows]
            den = np.sum(np.abs(ud) ** 2)
            c2 = 2j * poles[r].imag * np.sum(ud.conj() * (u.conj() @ B[:, cols])) / den if den > 0 else 0.0
            if c2 != 0 and np.isfinite(c2):
                v = np.sqrt(c2) * u
                # the branch of the one-reference formula: phi_d = sqrt(2 j omega_d A_dd) at the first drive
                ref = np.sqrt(2j * poles[r].imag * B[rows[0], cols[0]])
                if np.real(v[rows[0]] * np.conj(ref)) < 0:
                    v = -v
        if v is None:
            k = int(np.argmax(np.abs(u)))
            v = u * np.exp(-1j * np.angle(u[k])) / max(np.linalg.norm(u), 1e-300)
        phi[:, r] = v
    return phi, dofs, scaling


def weighted_rank_one(B: np.ndarray, w: np.ndarray, max_iter: int = 100, rtol: float = 1e-10) -> np.ndarray:
    """The unit vector ψ/‖ψ‖ of the rank-one ``ψ lᵀ`` nearest ``B`` in ``Σ w_ij |B_ij − ψ_i l_j|²``.

    Alternating least squares (each step exact for one factor, so the cost never rises), started from the
    dominant singular pair of ``√w ∘ B``. Why weighted: near a hammer the struck blade's FRFs carry a mass line
    about 1000 times the resonances, and its noise; unweighted, the few residues there took a disk mode's shape
    (48-blade seed 5, 322.7 Hz: 0.87 at the struck blade's outputs against the truth's 0.004, MAC 0.00).
    With equal weights it is the dominant singular vector.

    Parameters
    ----------
    B : ndarray of complex, shape (m, n)
    w : ndarray of float, shape (m, n)
        Positive weights.
    """
    u, s, vh = np.linalg.svd(np.sqrt(w) * B, full_matrices=False)
    if not s[0] > 0:
        return u[:, 0]                                       # no residue at all: no direction to weight
    part = s[0] * vh[0] / np.sqrt(np.mean(w, axis=0))         # the weighted factor's column scale taken out
    psi = np.zeros(B.shape[0], np.complex128)
    Bw = w * B
    for _ in range(max_iter):
        prev = psi
        psi = (Bw @ np.conj(part)) / (w @ np.abs(part) ** 2)
        part = (Bw.T @ np.conj(psi)) / (w.T @ np.abs(psi) ** 2)
        if prev.any() and abs(abs(np.vdot(prev, psi)) / (np.linalg.norm(prev) * np.linalg.norm(psi)) - 1) < rtol:
            break
    return psi / np.linalg.norm(psi)


def modal_model(
    frf: FRFSet,
    poles: np.ndarray,
    band: tuple[float, float] | None = None,
    quality: np.ndarray | None = None,
    method: str = "",
    residuals: bool = True,
    local_shapes: bool = True,
) -> ModalModel:
    """Fit residues (LSFD) for given poles and return the :class:`ModalModel`.

    Shapes live on the outputs when ``n_outputs >= n_inputs`` (roving response) and on the inputs
    otherwise (roving hammer, by reciprocity): the dominant singular vector of each residue matrix.
    With a driving point (an output label equal to an input label) they are scaled to unit modal mass
    (``A_r = phi phi^T / (2 j omega_d)``), otherwise to unit norm with the largest component real.

    The model's residues (and so its synthesis) come from one fit over the whole band. With ``local_shapes``
    (default) the shapes come from each mode's own local fit (:func:`local_residues`), which keeps the
    misfit of distant parts of the band out of them.
    """
    poles = np.asarray(poles, dtype=np.complex128).reshape(-1)
    srt = np.argsort(np.abs(poles), kind="stable")
    poles = poles[srt]
    if quality is not None:
        quality = np.asarray(quality, dtype=float).reshape(-1)[srt]
    A, lower, upper = lsfd(frf, poles, band, residuals)
    data_band = band_data(frf, band, per="none").band_hz
    # each residue weighted by its FRF's noise where several references share a shape (design §8.93)
    noise = band_floor(frf, data_band) if min(frf.n_outputs, frf.n_inputs) > 1 else None
    phi, dofs, scaling = shapes_from_residues(local_residues(frf, poles, data_band, A) if local_shapes else A, poles,
                                              frf, noise)
    f, z = modal_from_pole(poles)
    return ModalModel(
        frequencies_hz=f, damping_ratio=z, shapes=phi, dofs=dofs, quality=quality, residues=A,
        lower_residual=lower, upper_residual=upper, outputs=frf.outputs, inputs=frf.inputs, form=frf.form,
        band_hz=data_band, method=method, scaling=scaling,
    )


def synthesize(model: ModalModel, freq_hz: np.ndarray, form: str | None = None) -> FRFSet:
    """FRFs of a modal model with residues, on a frequency axis.

    Parameters
    ----------
    model : ModalModel
        Must carry residues (from :func:`modal_model`).
    freq_hz : ndarray, shape (n_freq,)
    form : str, optional
        Output form; default the model's.

    Returns
    -------
    FRFSet
        Shape (n_outputs, n_inputs, n_freq); NaN at 0 Hz when residual terms are present.
    """
    if model.residues is None:
        raise ValueError("synthesize: the modal model has no residues (fit it with ema.lsfd.modal_model)")
    form = form or model.form
    freq = np.asarray(freq_hz, dtype=np.float64)
    jw = 1j * 2 * np.pi * freq
    lam = model.poles
    A = model.residues
    H = _pole_terms(A, lam, freq, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        if model.lower_residual is not None and np.any(model.lower_residual != 0):
            H += model.lower_residual[:, :, None] * np.where(jw != 0, 1.0 / np.where(jw != 0, jw, 1) ** 2, np.nan)
        if model.upper_residual is not None:
            H += model.upper_residual[:, :, None]
    k = FRF_FORMS[form]
    if k:
        H = H * jw**k
    return FRFSet(freq_hz=freq, H=H, outputs=model.outputs, inputs=model.inputs, form=form)


def fit_quality(frf: FRFSet, model: ModalModel, band: tuple[float, float] | None = None) -> np.ndarray:
    """Fit quality of each FRF: ``1 - ||H - H_syn||^2 / ||H||^2`` over the band (1 = perfect).

    Returns
    -------
    ndarray, shape (n_outputs, n_inputs)
    """
    band = band or model.band_hz
    data = band_data(frf.with_form(model.form) if frf.form != model.form else frf, band, per="none")
    syn = synthesize(model, data.freq_hz).H
    ok = np.all(np.isfinite(syn), axis=(0, 1))
    H, S = data.H[:, :, ok], syn[:, :, ok]
    # squares of FRFs of 1e-156 or 1e+144 under- or overflow: divide each FRF by its peak first
    peak = np.max(np.abs(H), axis=2, keepdims=True)
    peak = np.where(peak > 0, peak, 1.0)
    num = np.sum(np.abs((H - S) / peak) ** 2, axis=2)
    den = np.sum(np.abs(H / peak) ** 2, axis=2)
    return 1.0 - num / np.where(den > 0, den, 1.0)


def dominance(frf: FRFSet, model: ModalModel) -> np.ndarray:
    """How much each mode dominates the measured response at its own natural frequency.

    ``d_r = max_f |H_f,r(f_r)| / |H_f(f_r)|``: the magnitude of mode r's own term in the synthesis,
    relative to the measured FRF, at the line nearest to ``f_r``, maximised over the FRFs. A physical
    resonance gives about 1; a computational pole that only patches the fit of a neighbour gives much
    less.

    Returns
    -------
    ndarray, shape (n_modes,)
    """
    if model.residues is None:
        raise ValueError("dominance: the modal model has no residues")
    data = frf.with_form(model.form) if frf.form != model.form else frf
    out = np.zeros(model.n_modes)
    valid = data.valid_lines()
    for r in range(model.n_modes):
        i = int(np.argmin(np.where(valid, np.abs(data.freq_hz - model.frequencies_hz[r]), np.inf)))
        jw = 1j * 2 * np.pi * data.freq_hz[i]
        lam = model.poles[r]
        A = model.residues[r]
        term = A / (jw - lam) + A.conj() / (jw - np.conj(lam))
        term = term * jw ** FRF_FORMS[model.form]
        meas = np.abs(data.H[:, :, i])
        out[r] = float(np.max(np.abs(term) / np.where(meas > 0, meas, np.inf)))
    return out
