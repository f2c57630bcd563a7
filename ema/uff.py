"""UFF input/output over pyuff: FRFs (58, 58b), nodes (15, 2411), units (164) and modes (55).

Reading is strict: anything that is not an FRF, not supported, inconsistent or malformed raises
:class:`~ema.errors.UFFError`, a ``ValueError`` whose one-line message names the file, the data set
(0-based index in the file) and the field.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyuff

from .errors import UFFError
from .fileio import atomic_path
from .frf import DOF, FRF_FORMS, FRFSet, Nodes, UnitSystem, merge_frfsets
from .modal import ModalModel

__all__ = [
    "FUNCTION_TYPES",
    "read_uff",
    "read_frfs",
    "read_nodes",
    "read_units",
    "read_modes",
    "write_frfs",
    "write_modes",
]

log = logging.getLogger(__name__)

#: UFF 58 record 6 field 1: function identification.
FUNCTION_TYPES: dict[int, str] = {
    0: "general or unknown",
    1: "time response",
    2: "auto spectrum",
    3: "cross spectrum",
    4: "frequency response function",
    5: "transmissibility",
    6: "coherence",
    7: "auto correlation",
    8: "cross correlation",
    9: "power spectral density",
    10: "energy spectral density",
    11: "probability density function",
    12: "spectrum",
    13: "cumulative frequency distribution",
    14: "peaks valley",
    15: "stress/cycles",
    16: "strain/cycles",
    17: "orbit",
    18: "mode indicator function",
    19: "force pattern",
    20: "partial power",
    21: "partial coherence",
    22: "eigenvalue",
    23: "eigenvector",
    24: "shock response spectrum",
    25: "finite impulse response filter",
    26: "multiple coherence",
    27: "order function",
    28: "phase compensation",
}

# UFF specific data types (record 9/10 field 1) that fix the FRF form.
_ORDINATE_FORM = {8: "receptance", 11: "mobility", 12: "accelerance"}
_FORM_ORDINATE = {v: k for k, v in _ORDINATE_FORM.items()}
_FORM_UNITS = {"receptance": "m/N", "mobility": "m/s/N", "accelerance": "m/s^2/N"}
_ABSCISSA_TYPES = {0: "unknown", 17: "time", 18: "frequency"}


# --------------------------------------------------------------------------------------------- reading
def _open(path: Path) -> tuple[Any, np.ndarray]:
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        uff = pyuff.UFF(str(path))
        types = np.asarray(uff.get_set_types(), dtype=int).reshape(-1)
    except Exception as exc:  # pyuff raises bare Exception (and others) on unreadable files
        raise UFFError(str(path), f"not a readable UFF file ({type(exc).__name__}: {exc})") from exc
    if types.size == 0:
        raise UFFError(str(path), "no UFF data sets found")
    return uff, types


def _read_set(uff: Any, path: Path, index: int, dtype: int) -> dict:
    try:
        dset = uff.read_sets(int(index))
    except Exception as exc:  # pyuff raises bare Exception (and others) on malformed data sets
        raise UFFError(
            str(path), f"malformed data set type {dtype} ({type(exc).__name__}: {exc})", index
        ) from exc
    if not isinstance(dset, dict):
        raise UFFError(str(path), f"pyuff returned {type(dset).__name__} for data set type {dtype}", index)
    return dset


def _unit_form(label: str) -> str | None:
    """Guess the FRF form from a unit label such as ``"(1/N)*(m/s²)"``; None when unclear."""
    text = label.lower().replace(" ", "")
    if re.search(r"m/s(\^?2|²|\*\*2|\ufffd|/s)", text) or re.search(r"(^|[^a-z])g($|[^a-z])", text):
        return "accelerance"
    if "m/s" in text:
        return "mobility"
    if re.search(r"(^|[^a-z])m($|[^a-z/])|m/n", text):
        return "receptance"
    return None


def _field(dset: dict, key: str, path: Path, index: int) -> Any:
    if key not in dset:
        raise UFFError(str(path), "required field missing", index, key)
    return dset[key]


def _frf_from_set(
    dset: dict, path: Path, index: int, form: str | None
) -> tuple[DOF, DOF, np.ndarray, np.ndarray, str, str]:
    func_type = int(_field(dset, "func_type", path, index))
    if func_type != 4:
        name = FUNCTION_TYPES.get(func_type, "unknown")
        raise UFFError(str(path), f"not an FRF (function type {func_type} = {name})", index, "func_type")
    abscissa = int(dset.get("abscissa_spec_data_type", 0))
    if abscissa not in (0, 18):
        name = _ABSCISSA_TYPES.get(abscissa, "other")
        raise UFFError(
            str(path), f"abscissa is {name} (type {abscissa}), expected frequency (18)", index,
            "abscissa_spec_data_type",
        )
    x = np.asarray(_field(dset, "x", path, index), dtype=np.float64).reshape(-1)
    data = np.asarray(_field(dset, "data", path, index)).reshape(-1)
    num_pts = int(dset.get("num_pts", data.size))
    if data.size != num_pts or x.size != num_pts:
        raise UFFError(
            str(path), f"header announces {num_pts} points but {data.size} values and {x.size} abscissae were read",
            index, "num_pts",
        )
    if not np.iscomplexobj(data):
        raise UFFError(
            str(path), f"unsupported: real-valued FRF (ord_data_type {dset.get('ord_data_type')}), expected complex",
            index, "ord_data_type",
        )
    if num_pts < 2 or not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
        raise UFFError(str(path), "frequency axis is not finite and strictly increasing", index, "x")
    if x[0] < 0:
        raise UFFError(str(path), f"frequency axis starts at {x[0]} Hz, expected >= 0", index, "x")
    ordinate = int(dset.get("ordinate_spec_data_type", 0))
    denom = int(dset.get("orddenom_spec_data_type", 0))
    units = str(dset.get("ordinate_axis_units_lab", "")).strip()
    if units.upper() == "NONE":
        units = ""
    den_units = str(dset.get("orddenom_axis_units_lab", "")).strip()
    if den_units and den_units.upper() != "NONE":
        units = f"{units}/{den_units}" if units else f"1/{den_units}"
    file_form = _ORDINATE_FORM.get(ordinate)
    if denom not in (0, 13) and file_form is not None:
        raise UFFError(
            str(path), f"unsupported: ordinate denominator type {denom}, expected excitation force (13)",
            index, "orddenom_spec_data_type",
        )
    if file_form is None:
        file_form = _unit_form(units + " " + str(dset.get("ordinate_axis_lab", "")))
    if form is not None and file_form is not None and form != file_form:
        raise UFFError(
            str(path), f"file says {file_form} (ordinate type {ordinate}, units {units!r}) but form={form!r} was given",
            index, "ordinate_spec_data_type",
        )
    use_form = file_form or form
    if use_form is None:
        raise UFFError(
            str(path),
            f"cannot tell the FRF form from ordinate type {ordinate} and units {units!r}; pass form=",
            index, "ordinate_spec_data_type",
        )
    rsp = (int(_field(dset, "rsp_node", path, index)), int(_field(dset, "rsp_dir", path, index)))
    ref = (int(_field(dset, "ref_node", path, index)), int(_field(dset, "ref_dir", path, index)))
    for label, key in ((rsp, "rsp_dir"), (ref, "ref_dir")):
        if not -6 <= label[1] <= 6:
            raise UFFError(str(path), f"direction {label[1]} outside -6..6", index, key)
    return rsp, ref, x, data.astype(np.complex128), use_form, units


def read_nodes(path: str | os.PathLike) -> Nodes | None:
    """Node coordinates from the data sets 15 / 2411 of a UFF file (None when there are none).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    Nodes or None
        All node data sets concatenated, in file order.
    """
    path = Path(path)
    uff, types = _open(path)
    ids, xyz = [], []
    for index, t in enumerate(types):
        if t not in (15, 2411):
            continue
        dset = _read_set(uff, path, index, int(t))
        try:
            n = np.asarray(dset["node_nums"], dtype=float).reshape(-1)
            coords = np.column_stack([np.asarray(dset[k], dtype=float).reshape(-1) for k in ("x", "y", "z")])
        except (KeyError, ValueError) as exc:
            raise UFFError(str(path), f"malformed node data set {t} ({exc})", index, "node_nums") from exc
        if coords.shape[0] != n.size:
            raise UFFError(str(path), f"{n.size} node numbers but {coords.shape[0]} coordinates", index, "x")
        ids.append(n.astype(np.int64))
        xyz.append(coords)
    if not ids:
        return None
    return Nodes(ids=np.concatenate(ids), xyz=np.vstack(xyz))


def read_units(path: str | os.PathLike) -> UnitSystem | None:
    """The units data set (164) of a UFF file, or None when there is none."""
    path = Path(path)
    uff, types = _open(path)
    for index, t in enumerate(types):
        if t != 164:
            continue
        dset = _read_set(uff, path, index, 164)
        try:
            return UnitSystem(
                code=int(dset["units_code"]),
                description=str(dset.get("units_description", "")).strip(),
                length=float(dset["length"]),
                force=float(dset["force"]),
                temperature=float(dset["temp"]),
            )
        except (KeyError, ValueError, TypeError) as exc:
            raise UFFError(str(path), f"malformed units data set ({exc})", index, "units_code") from exc
    return None


def read_uff(path: str | os.PathLike, form: str | None = None, skip_other: bool = False) -> FRFSet:
    """Read the FRFs (UFF 58 / 58b, function type 4) of one file into an :class:`FRFSet`.

    Parameters
    ----------
    path : path-like
    form : {"receptance", "mobility", "accelerance"}, optional
        FRF form to assume when the file does not state it (ordinate type 8 / 11 / 12 or a unit label);
        an error when it contradicts the file.
    skip_other : bool
        Skip data sets 58 that are not FRFs (coherence, spectra ...) instead of refusing the file, as
        long as at least one FRF is present. Other data set types (nodes, units, geometry) are always
        accepted alongside.

    Returns
    -------
    FRFSet
        Outputs / inputs in order of first appearance; nodes and units when the file carries them.

    Raises
    ------
    UFFError
        No FRF in the file, a non-FRF or unsupported 58 data set, inconsistent axes or forms, duplicate or
        missing (response, reference) pairs, or a malformed data set.
    FileNotFoundError
        ``path`` does not exist.
    """
    if form is not None and form not in FRF_FORMS:
        raise ValueError(f"form {form!r} not one of {sorted(FRF_FORMS)}")
    path = Path(path)
    uff, types = _open(path)
    idx58 = [i for i, t in enumerate(types) if t == 58]
    if not idx58:
        kinds = ", ".join(str(t) for t in dict.fromkeys(types.tolist()))
        raise UFFError(str(path), f"no FRF in file (no data set 58; data set types present: {kinds})")
    records: list[tuple[int, DOF, DOF, np.ndarray, np.ndarray, str, str]] = []
    first_refusal: UFFError | None = None
    for index in idx58:
        dset = _read_set(uff, path, index, 58)
        try:
            rsp, ref, x, data, frm, units = _frf_from_set(dset, path, index, form)
        except UFFError as err:
            if not (skip_other and err.field == "func_type"):
                raise
            first_refusal = first_refusal or err
            log.info("skipping %s", err)
            continue
        records.append((index, rsp, ref, x, data, frm, units))
    if not records:
        assert first_refusal is not None
        raise first_refusal
    i0, _, _, x0, _, form0, units0 = records[0]
    outputs: list[DOF] = []
    inputs: list[DOF] = []
    for index, rsp, ref, x, _, frm, _ in records:
        if x.shape != x0.shape or not np.allclose(x, x0, rtol=1e-9, atol=0.0):
            raise UFFError(
                str(path),
                f"inconsistent frequency axis: {x.size} lines [{x[0]}, {x[-1]}] Hz vs {x0.size} lines "
                f"[{x0[0]}, {x0[-1]}] Hz in data set {i0}",
                index, "x",
            )
        if frm != form0:
            raise UFFError(str(path), f"inconsistent FRF form: {frm} vs {form0} in data set {i0}", index,
                           "ordinate_spec_data_type")
        if rsp not in outputs:
            outputs.append(rsp)
        if ref not in inputs:
            inputs.append(ref)
    H = np.full((len(outputs), len(inputs), x0.size), np.nan + 0j)
    seen: dict[tuple[int, int], int] = {}
    for index, rsp, ref, _, data, _, _ in records:
        key = (outputs.index(rsp), inputs.index(ref))
        if key in seen:
            raise UFFError(
                str(path), f"FRF {rsp} / {ref} appears twice (also data set {seen[key]})", index, "rsp_node"
            )
        seen[key] = index
        H[key] = data
    if len(seen) != H.shape[0] * H.shape[1]:
        raise UFFError(
            str(path),
            f"incomplete FRF matrix: {len(seen)} of {len(outputs)} x {len(inputs)} (response, reference) "
            "pairs present; split it into files that each hold a full matrix",
            None, "ref_node",
        )
    nodes = read_nodes(path) if any(t in (15, 2411) for t in types) else None
    units = read_units(path) if 164 in types else None
    return FRFSet(
        freq_hz=x0,
        H=H,
        outputs=tuple(outputs),
        inputs=tuple(inputs),
        form=form0,
        units=units0,
        nodes=nodes,
        unit_system=units,
        sources=(str(path),),
    )


def read_frfs(paths: Sequence[str | os.PathLike], form: str | None = None, skip_other: bool = False) -> FRFSet:
    """Read several UFF files and merge them into one :class:`FRFSet` (roving hammer / response).

    See :func:`read_uff` and :func:`ema.frf.merge_frfsets`.
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("read_frfs: no files given")
    sets = [read_uff(p, form=form, skip_other=skip_other) for p in paths]
    if len(sets) == 1:
        return sets[0]
    return merge_frfsets(sets)


def read_modes(path: str | os.PathLike) -> ModalModel:
    """Read normal-mode data sets (UFF 55, analysis type 2 or 3) into a :class:`ModalModel`.

    Shapes are put on the DOFs ``(node, 1..3)`` (translations) and ``(node, 4..6)`` when rotations are
    present. Damping is the modal viscous damping ratio of the file (0 when absent).
    """
    path = Path(path)
    uff, types = _open(path)
    idx = [i for i, t in enumerate(types) if t == 55]
    if not idx:
        raise UFFError(str(path), "no mode shapes in file (no data set 55)")
    freqs, damps, shapes = [], [], []
    dofs: tuple[DOF, ...] | None = None
    for index in idx:
        dset = _read_set(uff, path, index, 55)
        analysis = int(dset.get("analysis_type", 0))
        if analysis == 2:
            f = float(_field(dset, "freq", path, index))
            z = float(dset.get("modal_damp_vis", 0.0))
        elif analysis in (3, 7):
            lam = complex(float(_field(dset, "eig_r", path, index)), float(_field(dset, "eig_i", path, index)))
            wn = abs(lam)
            f, z = wn / (2 * np.pi), (-lam.real / wn if wn > 0 else 0.0)
        else:
            raise UFFError(str(path), f"unsupported analysis type {analysis}, expected 2 or 3", index,
                           "analysis_type")
        nodes = np.asarray(_field(dset, "node_nums", path, index)).astype(np.int64).reshape(-1)
        comps = [k for k in ("r1", "r2", "r3", "r4", "r5", "r6") if k in dset]
        labels = tuple((int(n), d + 1) for n in nodes for d in range(len(comps)))
        values = np.column_stack([np.asarray(dset[k]).reshape(-1) for k in comps]).reshape(-1)
        if dofs is None:
            dofs = labels
        elif labels != dofs:
            raise UFFError(str(path), "mode shape defined on other nodes than data set " f"{idx[0]}", index,
                           "node_nums")
        freqs.append(f)
        damps.append(z)
        shapes.append(values.astype(np.complex128))
    assert dofs is not None
    return ModalModel(
        frequency_hz=np.asarray(freqs), damping_ratio=np.asarray(damps), shapes=np.column_stack(shapes), dofs=dofs
    )


# --------------------------------------------------------------------------------------------- writing
def _atomic_write(path: Path, dsets: list[dict]) -> None:
    """Write data sets to ``path`` through a temporary file in the same folder and ``os.replace``."""
    with atomic_path(path) as tmp:
        tmp.unlink()  # pyuff appends to existing files; start from nothing
        pyuff.UFF(str(tmp)).write_sets(dsets, mode="add")


def _even_axis(freq: np.ndarray) -> bool:
    """True when pyuff's even-spacing header (``%13.5e`` min and increment) reproduces ``freq`` exactly."""
    f0, df = float(f"{freq[0]:13.5e}"), float(f"{freq[1] - freq[0]:13.5e}")
    rebuilt = f0 + np.arange(freq.size) * df
    return bool(np.all(np.abs(rebuilt - freq) <= 1e-14 * max(1.0, float(np.max(np.abs(freq))))))


def write_frfs(path: str | os.PathLike, frf: FRFSet, binary: bool = True, id1: str = "bladetwin FRF") -> None:
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

    Notes
    -----
    The frequency axis is written as even spacing only when the ASCII header's ``%13.5e`` minimum and
    increment rebuild it exactly; otherwise every abscissa is written with the values.
    """
    path = Path(path)
    freq = frf.freq_hz
    even = _even_axis(freq)
    units = frf.units or _FORM_UNITS[frf.form]
    dsets = []
    for o, rsp in enumerate(frf.outputs):
        for i, ref in enumerate(frf.inputs):
            dsets.append(
                pyuff.prepare_58(
                    binary=int(bool(binary)),
                    id1=id1[:80],
                    id2="NONE",
                    id3="NONE",
                    id4="NONE",
                    id5="NONE",
                    func_type=4,
                    rsp_node=int(rsp[0]),
                    rsp_dir=int(rsp[1]),
                    ref_node=int(ref[0]),
                    ref_dir=int(ref[1]),
                    ord_data_type=6,
                    abscissa_spacing=int(even),
                    abscissa_min=float(freq[0]),
                    abscissa_inc=float(freq[1] - freq[0]) if even else 0.0,
                    abscissa_spec_data_type=18,
                    abscissa_axis_units_lab="Hz",
                    ordinate_spec_data_type=_FORM_ORDINATE[frf.form],
                    ordinate_axis_units_lab=units[:20],
                    orddenom_spec_data_type=13,
                    orddenom_axis_units_lab="NONE",
                    data=np.ascontiguousarray(frf.H[o, i]),
                    x=np.ascontiguousarray(freq),
                    rsp_ent_name="NONE",
                    ref_ent_name="NONE",
                )
            )
    _atomic_write(path, dsets)


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
                freq=float(model.frequency_hz[m]), modal_m=1.0,
                modal_damp_vis=float(model.damping_ratio[m]), modal_damp_his=0.0,
                node_nums=np.asarray(nodes, dtype=int), **kw,
            )
        )
    _atomic_write(path, dsets)
