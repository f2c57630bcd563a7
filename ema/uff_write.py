"""UFF output over pyuff: FRFs and their coherence (58, 58b; double or single precision) and modes (55), atomically.

Reading is in :mod:`ema.uff`, which also exports :func:`write_frfs` and :func:`write_modes`.
"""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pyuff

from .errors import EMAError
from .fileio import atomic_path
from .frf import DOF, FRFSet, line_ranges
from .modal import ModalModel
from .uff_format import FORM_ORDINATE, FORM_UNITS, delimiters

__all__ = ["write_frfs", "write_modes", "even_axis"]

log = logging.getLogger(__name__)


def _atomic_write(path: Path, dsets: list[dict], single: bool = False) -> None:
    """Write data sets to ``path`` through a temporary file in the same folder and ``os.replace``."""
    with atomic_path(path) as tmp:
        raw = _pyuff_bytes(dsets)
        tmp.write_bytes(_as_single(raw) if single else raw)


def _pyuff_bytes(dsets: list[dict]) -> bytes:
    """pyuff's bytes of ``dsets``, each set written on its own and the bytes joined in order.

    Why: pyuff re-reads the whole file after every set it appends (``UFF.refresh``), so one file of n sets costs
    O(n²): a 6-blade campaign's full-assembly file took 2.2 s, and 0.65 s set by set. A set appended to a file does
    not depend on the sets before it, so the joined bytes are those of one file (the campaigns are byte-identical).
    """
    out = []
    with tempfile.TemporaryDirectory(prefix="bladetwin-uff-") as scratch:
        one = Path(scratch) / "set.uff"
        for dset in dsets:
            one.unlink(missing_ok=True)
            pyuff.UFF(str(one)).write_sets(dset, mode="add")
            out.append(one.read_bytes())
    return b"".join(out)


def even_axis(freq: np.ndarray) -> bool:
    """True when pyuff's even-spacing header (``%13.5e`` min and increment) reproduces ``freq`` exactly."""
    f0, df = float(f"{freq[0]:13.5e}"), float(f"{freq[1] - freq[0]:13.5e}")
    rebuilt = f0 + np.arange(freq.size) * df
    return bool(np.all(np.abs(rebuilt - freq) <= 1e-14 * max(1.0, float(np.max(np.abs(freq))))))


def _as_single(raw: bytes) -> bytes:
    """pyuff's 58b output (double: complex type 6, real type 4) rewritten as single (types 5 and 2).

    pyuff writes every binary value as a double whatever record 7 says, so single precision is made here:
    each data set's payload is cast to little-endian float32, and the ID line's byte count and record 7's
    ordinate type are updated. Nothing else changes (headers, labels, the axis).
    """
    out: list[bytes] = []
    marks = delimiters(raw)
    done = 0
    for start, end in zip(marks[0::2], marks[1::2], strict=False):  # opening and closing delimiters
        block = raw[start:end]
        lines = block.splitlines(True)
        header = lines[:13]
        payload = block[len(b"".join(header)):]
        id_line, rec7 = header[1].decode("ascii"), header[8].decode("ascii")
        single = {6: 5, 4: 2}.get(int(rec7[0:10]))  # complex FRFs, real coherence
        if id_line[6:13] != "b     1" or single is None:
            raise EMAError("single-precision UFF: expected pyuff's little-endian double 58b output")
        n_values = len(payload) // 8
        values = np.frombuffer(payload[: 8 * n_values], dtype="<f8").astype("<f4")
        header[1] = (id_line[:31] + f"{values.nbytes:12d}" + id_line[43:]).encode("ascii")
        header[8] = (f"{single:10d}" + rec7[10:]).encode("ascii")
        out += [raw[done:start], b"".join(header), values.tobytes(), payload[8 * n_values:]]
        done = end
    out.append(raw[done:])
    return b"".join(out)


def _dset_58(binary: bool, id1: str, func_type: int, rsp: DOF, ref: DOF, freq: np.ndarray, even: bool,
             data: np.ndarray, ordinate: tuple[int, str], denom: int) -> dict:
    """One pyuff data set 58: an FRF (function type 4, complex) or a coherence (type 6, real)."""
    return pyuff.prepare_58(
        binary=int(bool(binary)), id1=id1[:80], id2="NONE", id3="NONE", id4="NONE", id5="NONE",
        func_type=func_type, rsp_node=int(rsp[0]), rsp_dir=int(rsp[1]), ref_node=int(ref[0]), ref_dir=int(ref[1]),
        ord_data_type=6 if np.iscomplexobj(data) else 4, abscissa_spacing=int(even), abscissa_min=float(freq[0]),
        abscissa_inc=float(freq[1] - freq[0]) if even else 0.0, abscissa_spec_data_type=18,
        abscissa_axis_units_lab="Hz", ordinate_spec_data_type=ordinate[0], ordinate_axis_units_lab=ordinate[1][:20],
        orddenom_spec_data_type=denom, orddenom_axis_units_lab="NONE", data=np.ascontiguousarray(data),
        x=np.ascontiguousarray(freq), rsp_ent_name="NONE", ref_ent_name="NONE",
    )


def _check_coherence(path: Path, frf: FRFSet, coherence: Any) -> np.ndarray:
    """``coherence`` as float64 of the FRFs' shape, every value in [0, 1]; EMAError otherwise."""
    coh = np.asarray(coherence, dtype=np.float64)
    if coh.shape != frf.H.shape:
        raise EMAError(f"{path}: coherence has shape {coh.shape}, expected the FRFs' {frf.H.shape}")
    bad = ~(np.isfinite(coh) & (coh >= 0) & (coh <= 1))
    if bad.any():
        o, i, f = (int(k) for k in np.argwhere(bad)[0])
        raise EMAError(f"{path}: coherence {frf.outputs[o]} / {frf.inputs[i]} is {coh[o, i, f]!r} at "
                       f"{frf.freq_hz[f]} Hz, expected a value in [0, 1]")
    return coh


def write_frfs(
    path: str | os.PathLike, frf: FRFSet, binary: bool = True, id1: str = "bladetwin FRF", precision: str = "double",
    coherence: np.ndarray | None = None,
) -> None:
    """Write an :class:`FRFSet` as UFF 58 data sets (one per FRF), atomically.

    Parameters
    ----------
    path : path-like
        Target file; replaced if it exists.
    frf : FRFSet
    binary : bool
        Write 58b (binary, IEEE double values: a lossless round trip). ASCII 58 keeps 12 significant
        digits of each value (pyuff's ``%20.11e``), i.e. about 5e-12 relative.
    id1 : str
        First ID line of every data set.
    precision : {"double", "single"}
        Binary value size. "single" (ordinate type 5, IEEE float32: 6e-8 relative, far below any measured
        FRF's noise) halves the file, as many analyser exports do; the virtual rig writes its campaigns so.
    coherence : ndarray, shape (n_outputs, n_inputs, n_freq), optional
        Ordinary coherence of each FRF, in [0, 1]: written after the FRFs as one data set 58 per FRF
        (function type 6 "coherence", same DOFs and axis, real values, ordinate type 0 "unknown", as
        analysers export it). :func:`read_coherence` reads it back; :func:`read_uff` passes over it.

    Raises
    ------
    EMAError
        A NaN or infinite value on a line above 0 Hz: UFF has no code for a missing value, and pyuff would
        write 0 (or the largest double) in its place. A coherence of the wrong shape or outside [0, 1].

    Notes
    -----
    The frequency axis is written as even spacing only when the ASCII header's ``%13.5e`` minimum and
    increment rebuild it exactly; otherwise every abscissa is written with the values. A 0 Hz line with a
    non-finite value (a receptance converted from another form, a synthesis with residual terms) is left
    out of the file, as it is left out of every fit (and so is its coherence).
    """
    path = Path(path)
    if precision not in ("double", "single"):
        raise EMAError(f"precision {precision!r}: expected 'double' or 'single'")
    if precision == "single" and not binary:
        raise EMAError("precision 'single' needs binary=True (ASCII 58 values are written as text)")
    coh = None if coherence is None else _check_coherence(path, frf, coherence)
    bad = ~np.isfinite(frf.H)
    if bad.any():
        dc = frf.freq_hz == 0
        wrong = bad & ~dc
        if wrong.any():
            o, i = (int(k) for k in np.argwhere(wrong.any(axis=2))[0])
            raise EMAError(
                f"{path}: cannot write FRF {frf.outputs[o]} / {frf.inputs[i]}: non-finite values on "
                f"{line_ranges(frf.freq_hz, wrong[o, i])}; UFF has no code for a missing value"
            )
        log.info("%s: 0 Hz line left out (non-finite values there)", path)
        frf = frf.band(float(frf.freq_hz[~dc][0]), float(frf.freq_hz[-1]))
        coh = None if coh is None else coh[..., ~dc]
    freq = frf.freq_hz
    even = even_axis(freq)
    ordinate = (FORM_ORDINATE[frf.form], frf.units or FORM_UNITS[frf.form])
    pairs = [(o, i) for o in range(frf.n_outputs) for i in range(frf.n_inputs)]
    dsets = [_dset_58(binary, id1, 4, frf.outputs[o], frf.inputs[i], freq, even, frf.H[o, i], ordinate, 13)
             for o, i in pairs]
    if coh is not None:
        dsets += [_dset_58(binary, id1, 6, frf.outputs[o], frf.inputs[i], freq, even, coh[o, i], (0, "NONE"), 0)
                  for o, i in pairs]
    _atomic_write(path, dsets, single=precision == "single")


def write_modes(path: str | os.PathLike, model: ModalModel, id1: str = "bladetwin modes") -> None:
    """Write a :class:`ModalModel` as UFF 55 data sets (normal modes, real part of the shapes), atomically.

    Shapes are rotated so that their largest component is real before the real part is taken; DOFs with
    a negative direction are written with the sign flipped onto the positive axis. Rotational DOFs (4..6)
    are written when present (6 values per node).
    """
    path = Path(path)
    nodes = sorted({n for n, _ in model.dofs})
    n_comp = 6 if any(abs(d) > 3 for _, d in model.dofs) else 3
    dsets = []
    for m in range(model.n_modes):
        phi = model.shapes[:, m]
        k = int(np.argmax(np.abs(phi)))
        phi = phi * np.exp(-1j * np.angle(phi[k])) if abs(phi[k]) > 0 else phi
        r = np.zeros((n_comp, len(nodes)))
        for (node, d), value in zip(model.dofs, phi.real, strict=True):
            if d == 0:
                continue
            r[abs(d) - 1, nodes.index(node)] += np.sign(d) * value
        kw = {f"r{c + 1}": r[c] for c in range(n_comp)}
        dsets.append(
            pyuff.prepare_55(
                id1=id1[:80], id2="NONE", id3="NONE", id4="NONE", id5="NONE",
                model_type=1, analysis_type=2, data_ch=2 if n_comp == 3 else 3, spec_data_type=8,
                data_type=2, n_data_per_node=n_comp, load_case=1, mode_n=m + 1,
                freq=float(model.frequencies_hz[m]), modal_m=1.0,
                modal_damp_vis=float(model.damping_ratio[m]), modal_damp_his=0.0,
                node_nums=np.asarray(nodes, dtype=int), **kw,
            )
        )
    _atomic_write(path, dsets)
