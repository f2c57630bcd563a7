"""UFF input/output over pyuff: FRFs (58, 58b), their coherence, nodes (15, 2411), units (164) and modes (55).

Reading is strict: anything that is not an FRF, not supported, inconsistent or malformed raises
:class:`~ema.errors.UFFError`, a ``ValueError`` whose one-line message names the file, the data set
(0-based index in the file) and the field. Coherence data sets (58, function type 6, one per FRF) may sit
beside the FRFs: :func:`read_uff` checks and passes over them, :func:`read_coherence` returns them. The format's
codes and block checks are in :mod:`ema.uff_format`; writing is in :mod:`ema.uff_write` (exported here).
"""

from __future__ import annotations

import logging
import os
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .errors import UFFError
from .frf import DOF, FRF_FORMS, FRFSet, Nodes, UnitSystem, line_ranges, merge_frfsets
from .modal import ModalModel
from .uff_format import ABSCISSA_TYPES, FUNCTION_TYPES, ORDINATE_FORM, open_uff, read_set, required_field
from .uff_write import write_frfs, write_modes

__all__ = [
    "FUNCTION_TYPES",
    "read_uff",
    "read_coherence",
    "read_frfs",
    "read_nodes",
    "read_units",
    "read_modes",
    "write_frfs",
    "write_modes",
]

log = logging.getLogger(__name__)


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


def _axis_and_data(dset: dict, path: Path, index: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """A type-58 set's frequency axis and its values, checked: a frequency abscissa and as many values as the
    header announces (``what`` names the record in the message: "" for an FRF, "coherence ")."""
    abscissa = int(dset.get("abscissa_spec_data_type", 0))
    if abscissa not in (0, 18):
        name = ABSCISSA_TYPES.get(abscissa, "other")
        raise UFFError(str(path), f"{what}abscissa is {name} (type {abscissa}), expected frequency (18)", index,
                       "abscissa_spec_data_type")
    x = np.asarray(required_field(dset, "x", path, index), dtype=np.float64).reshape(-1)
    data = np.asarray(required_field(dset, "data", path, index)).reshape(-1)
    num_pts = int(dset.get("num_pts", data.size))
    if data.size != num_pts or x.size != num_pts:
        raise UFFError(
            str(path), f"{what}header announces {num_pts} points but {data.size} values and {x.size} abscissae "
            "were read (short or damaged data set)", index, "num_pts",
        )
    return x, data


def _dof_pair(dset: dict, path: Path, index: int) -> tuple[DOF, DOF]:
    """(response, reference) (node, direction) of a type-58 set, directions checked."""
    rsp = (int(required_field(dset, "rsp_node", path, index)), int(required_field(dset, "rsp_dir", path, index)))
    ref = (int(required_field(dset, "ref_node", path, index)), int(required_field(dset, "ref_dir", path, index)))
    for label, key in ((rsp, "rsp_dir"), (ref, "ref_dir")):
        if not -6 <= label[1] <= 6:
            raise UFFError(str(path), f"direction {label[1]} outside -6..6", index, key)
    return rsp, ref


def _frf_from_set(
    dset: dict, path: Path, index: int, form: str | None
) -> tuple[DOF, DOF, np.ndarray, np.ndarray, str, str]:
    func_type = int(required_field(dset, "func_type", path, index))
    if func_type != 4:
        name = FUNCTION_TYPES.get(func_type, "unknown")
        raise UFFError(str(path), f"not an FRF (function type {func_type} = {name})", index, "func_type")
    x, data = _axis_and_data(dset, path, index, "")
    if not np.iscomplexobj(data):
        raise UFFError(
            str(path), f"unsupported: real-valued FRF (ord_data_type {dset.get('ord_data_type')}), expected complex",
            index, "ord_data_type",
        )
    if x.size < 2 or not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
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
    file_form = ORDINATE_FORM.get(ordinate)
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
    rsp, ref = _dof_pair(dset, path, index)
    return rsp, ref, x, data.astype(np.complex128), use_form, units


def _coherence_from_set(dset: dict, path: Path, index: int) -> tuple[DOF, DOF, np.ndarray, np.ndarray]:
    """(response, reference, axis, values) of a coherence data set (58, function type 6), checked."""
    x, data = _axis_and_data(dset, path, index, "coherence ")
    if np.iscomplexobj(data):
        raise UFFError(str(path), f"coherence must be real, found complex values (ord_data_type "
                       f"{dset.get('ord_data_type')})", index, "ord_data_type")
    data = data.astype(np.float64)
    # float32 files round values at 1 up by a few 1e-8
    if not np.all(np.isfinite(data)) or np.any(data < 0) or np.any(data > 1 + 1e-6):
        bad = data[~(np.isfinite(data) & (data >= 0) & (data <= 1 + 1e-6))][0]
        raise UFFError(str(path), f"coherence value {bad:.6g} outside [0, 1] (damaged data set)", index, "data")
    rsp, ref = _dof_pair(dset, path, index)
    return rsp, ref, x, np.minimum(data, 1.0)


def _coherence_matrix(path: Path, records: list, outputs: list, inputs: list, x0: np.ndarray) -> np.ndarray | None:
    """Coherence records on the FRF matrix's layout (NaN where an FRF has none); None without records."""
    if not records:
        return None
    coh = np.full((len(outputs), len(inputs), x0.size), np.nan)
    seen: dict[tuple[int, int], int] = {}
    for index, rsp, ref, x, data in records:
        if rsp not in outputs or ref not in inputs:
            raise UFFError(str(path), f"coherence for {rsp} / {ref} but the file has no such FRF", index, "rsp_node")
        if x.shape != x0.shape or not np.allclose(x, x0, rtol=1e-9, atol=0.0):
            raise UFFError(str(path), f"coherence axis of {x.size} lines [{x[0] if x.size else '-'}, "
                           f"{x[-1] if x.size else '-'}] Hz differs from the FRFs' {x0.size} lines", index, "x")
        key = (outputs.index(rsp), inputs.index(ref))
        if key in seen:
            raise UFFError(str(path), f"coherence {rsp} / {ref} appears twice (also data set {seen[key]})", index,
                           "rsp_node")
        seen[key] = index
        coh[key] = data
    return coh


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
    uff, types = open_uff(path)
    ids, xyz = [], []
    for index, t in enumerate(types):
        if t not in (15, 2411):
            continue
        dset = read_set(uff, path, index, int(t))
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
    uff, types = open_uff(path)
    for index, t in enumerate(types):
        if t != 164:
            continue
        dset = read_set(uff, path, index, 164)
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


def _signal_problem(h: np.ndarray) -> str | None:
    """Why one FRF carries no signal (all zero, or one constant value on every finite line), else None."""
    finite = h[np.isfinite(h)]
    if finite.size == 0:
        return "no finite value"
    if not np.any(finite != 0):
        return "every value is zero: the FRF carries no signal"
    # a few rounding units of the values themselves: only a truly constant record is refused
    if np.all(np.abs(finite - finite[0]) <= 4 * np.finfo(np.float64).eps * np.abs(finite[0])):
        return f"every value is {complex(finite[0]):.6g}: a constant FRF carries no signal"
    return None


def read_uff(
    path: str | os.PathLike, form: str | None = None, skip_other: bool = False, nonfinite: str = "refuse"
) -> FRFSet:
    """Read the FRFs (UFF 58 / 58b, function type 4) of one file into an :class:`FRFSet`.

    Coherence data sets (function type 6) are checked (see :func:`read_coherence`) and left out of the FRFs.

    Parameters
    ----------
    path : path-like
    form : {"receptance", "mobility", "accelerance"}, optional
        FRF form to assume when the file does not state it (ordinate type 8 / 11 / 12 or a unit label);
        an error when it contradicts the file.
    skip_other : bool
        Skip data sets 58 that are neither FRFs nor coherence (spectra, multiple coherence ...) instead
        of refusing the file, as long as at least one FRF is present. Other data set types (nodes, units,
        geometry) are always accepted alongside.
    nonfinite : {"refuse", "drop"}
        What to do with NaN or infinite values: refuse the file (default), or remove the lines that hold
        them from every FRF, with a warning naming the data sets and frequencies dropped. A non-finite 0 Hz
        line is kept either way (it is left out of fits; see :class:`~ema.frf.FRFSet`).

    Returns
    -------
    FRFSet
        Outputs / inputs in order of first appearance; nodes and units when the file carries them.

    Raises
    ------
    UFFError
        No FRF in the file, a non-FRF or unsupported 58 data set, inconsistent axes or forms, duplicate or
        missing (response, reference) pairs, a malformed data set, a file that ends inside a data set
        (truncated, or without its final ``-1``), a binary data set shorter than its header says, non-finite
        values (with ``nonfinite="refuse"``), an FRF that is zero or constant on every line, a damaged
        coherence data set, or a path that is a directory.
    FileNotFoundError
        ``path`` does not exist.
    """
    return _read_file(path, form, skip_other, nonfinite)[0]


def read_coherence(
    path: str | os.PathLike, form: str | None = None, skip_other: bool = False, nonfinite: str = "refuse"
) -> np.ndarray | None:
    """The coherence data sets (UFF 58 / 58b, function type 6) of one file, on its FRFs' layout.

    Parameters are those of :func:`read_uff`; the file is read and checked as it reads it.

    Returns
    -------
    ndarray of float64, shape (n_outputs, n_inputs, n_freq), or None
        ``coh[o, i]`` belongs to ``read_uff(path).H[o, i]`` (same outputs, inputs and lines, also after
        ``nonfinite="drop"``); NaN for an FRF without a coherence data set. None when the file has none.

    Raises
    ------
    UFFError
        Everything :func:`read_uff` refuses, and a coherence data set that is damaged (point count, values
        outside [0, 1] or non-finite, complex values), on another axis than the FRFs, for a
        (response, reference) pair without an FRF, or present twice.
    """
    return _read_file(path, form, skip_other, nonfinite)[1]


def _read_file(
    path: str | os.PathLike, form: str | None, skip_other: bool, nonfinite: str
) -> tuple[FRFSet, np.ndarray | None]:
    """The FRFs and the coherence of one file (see :func:`read_uff`, :func:`read_coherence`)."""
    if form is not None and form not in FRF_FORMS:
        raise ValueError(f"form {form!r} not one of {sorted(FRF_FORMS)}")
    if nonfinite not in ("refuse", "drop"):
        raise ValueError(f"nonfinite {nonfinite!r}: expected 'refuse' or 'drop'")
    path = Path(path)
    uff, types = open_uff(path)
    idx58 = [i for i, t in enumerate(types) if t == 58]
    if not idx58:
        kinds = ", ".join(str(t) for t in dict.fromkeys(types.tolist()))
        raise UFFError(str(path), f"no FRF in file (no data set 58; data set types present: {kinds})")
    records: list[tuple[int, DOF, DOF, np.ndarray, np.ndarray, str, str]] = []
    coh_records: list[tuple[int, DOF, DOF, np.ndarray, np.ndarray]] = []
    first_refusal: UFFError | None = None
    for index in idx58:
        dset = read_set(uff, path, index, 58)
        if dset.get("func_type") == 6:  # coherence beside the FRFs (as write_frfs(coherence=...) puts it)
            coh_records.append((index, *_coherence_from_set(dset, path, index)))
            continue
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
        if first_refusal is None:
            raise UFFError(str(path), "no FRF in file (only coherence data sets)")
        raise first_refusal
    x0, H, outputs, inputs, seen = _frf_matrix(path, records)
    form0, units0 = records[0][5], records[0][6]
    coherence = _coherence_matrix(path, coh_records, outputs, inputs, x0)
    x_all = x0
    x0, H = _nonfinite(path, x0, H, seen, nonfinite)
    if coherence is not None and x0.size != x_all.size:
        coherence = coherence[..., np.isin(x_all, x0)]
    nodes = read_nodes(path) if any(t in (15, 2411) for t in types) else None
    units = read_units(path) if 164 in types else None
    frf = FRFSet(
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
    return frf, coherence


def _frf_matrix(path: Path, records: list) -> tuple[np.ndarray, np.ndarray, list, list, dict]:
    """The FRF records of one file as (axis, H, outputs, inputs, {(o, i): data set}), checked for consistency."""
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
    for (o, i), index in seen.items():
        why = _signal_problem(H[o, i])
        if why is not None:
            raise UFFError(str(path), f"FRF {outputs[o]} / {inputs[i]}: {why}", index, "data")
    return x0, H, outputs, inputs, seen


def _nonfinite(
    path: Path, freq: np.ndarray, H: np.ndarray, seen: dict[tuple[int, int], int], policy: str
) -> tuple[np.ndarray, np.ndarray]:
    """Refuse (or, with ``policy="drop"``, cut out with a warning) the lines that hold non-finite values."""
    bad = ~np.isfinite(H)
    bad[:, :, freq == 0] = False  # a non-finite 0 Hz line is legitimate (see FRFSet) and never fitted
    if not bad.any():
        return freq, H
    hit = sorted((index, key) for key, index in seen.items() if bad[key].any())
    index, (o, i) = hit[0]
    others = f" (and {len(hit) - 1} more data sets)" if len(hit) > 1 else ""
    if policy == "refuse":
        raise UFFError(
            str(path), f"non-finite values (NaN or inf) on {line_ranges(freq, bad[o, i])}{others}; refusing the"
            " file rather than fitting without those lines", index, "data",
        )
    drop = bad.any(axis=(0, 1))
    if int((~drop).sum()) < 2:
        raise UFFError(str(path), f"non-finite values on {line_ranges(freq, drop)}: fewer than 2 lines left", index,
                       "data")
    msg = (f"{path}: dropped {line_ranges(freq, drop)} from every FRF: non-finite values in data set"
           f"{'s' if len(hit) > 1 else ''} {', '.join(str(k) for k, _ in hit)}")
    warnings.warn(msg, stacklevel=4)  # the caller of read_uff / read_coherence
    return freq[~drop], H[:, :, ~drop]


def read_frfs(
    paths: Sequence[str | os.PathLike], form: str | None = None, skip_other: bool = False, nonfinite: str = "refuse"
) -> FRFSet:
    """Read several UFF files and merge them into one :class:`FRFSet` (roving hammer / response).

    See :func:`read_uff` and :func:`ema.frf.merge_frfsets`.
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("read_frfs: no files given")
    sets = [read_uff(p, form=form, skip_other=skip_other, nonfinite=nonfinite) for p in paths]
    if len(sets) == 1:
        return sets[0]
    return merge_frfsets(sets)


def read_modes(path: str | os.PathLike) -> ModalModel:
    """Read normal-mode data sets (UFF 55, analysis type 2 or 3) into a :class:`ModalModel`.

    Shapes are put on the DOFs ``(node, 1..3)`` (translations) and ``(node, 4..6)`` when rotations are
    present. Damping is the modal viscous damping ratio of the file (0 when absent).
    """
    path = Path(path)
    uff, types = open_uff(path)
    idx = [i for i, t in enumerate(types) if t == 55]
    if not idx:
        raise UFFError(str(path), "no mode shapes in file (no data set 55)")
    freqs, damps, shapes = [], [], []
    dofs: tuple[DOF, ...] | None = None
    for index in idx:
        dset = read_set(uff, path, index, 55)
        analysis = int(dset.get("analysis_type", 0))
        if analysis == 2:
            f = float(required_field(dset, "freq", path, index))
            z = float(dset.get("modal_damp_vis", 0.0))
        elif analysis in (3, 7):
            lam = complex(float(required_field(dset, "eig_r", path, index)),
                          float(required_field(dset, "eig_i", path, index)))
            wn = abs(lam)
            f, z = wn / (2 * np.pi), (-lam.real / wn if wn > 0 else 0.0)
        else:
            raise UFFError(str(path), f"unsupported analysis type {analysis}, expected 2 or 3", index,
                           "analysis_type")
        nodes = np.asarray(required_field(dset, "node_nums", path, index)).astype(np.int64).reshape(-1)
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
        frequencies_hz=np.asarray(freqs), damping_ratio=np.asarray(damps), shapes=np.column_stack(shapes), dofs=dofs
    )
