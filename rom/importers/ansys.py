"""ANSYS Mechanical APDL ``.full`` files (stiffness and mass), with nodes and components from a ``.cdb`` archive.

Reading goes through ``ansys-mapdl-reader`` (optional extra ``bladetwin[ansys]``, imported lazily: it pulls in
VTK). What the reader gives and what this module does with it:

* ``load_km()`` returns the **upper triangle** of K and M (as its documentation shows, ``k += triu(k, 1).T``
  restores the matrix); it is expanded here, in component numbering.
* **Constrained DOFs** are kept by the reader as zero rows and columns and listed in ``full.const``; they
  become the component's constrained DOFs (see :mod:`rom.importers.build`).
* ``dof_ref`` gives node and direction (0, 1, 2 = x, y, z) per row. Only 3-D solid models with UX, UY, UZ
  are accepted: other DOF sets (rotations, temperatures) are refused.
* The ``.full`` file holds no geometry: node coordinates and named node components come from the ``.cdb``
  archive written by ``CDWRITE`` (``Archive.nnum``, ``Archive.nodes``, ``Archive.node_components``). Without
  one, the coordinates are NaN and the mass/units check and the grid builder are not available.
* **Units**: neither file says which system it is in; the caller names it (``units``, e.g. ``"mm-t-s"``, the
  usual one of ANSYS models in millimetres) and everything is converted to SI.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from ..component import Component
from .build import dof_layout, finish_component, matrix_to_csr
from .errors import MissingDependencyError, ModelImportError
from .units import UnitSystem, unit_system

__all__ = ["read_ansys_full", "read_ansys_archive", "INSTALL_HINT"]

log = logging.getLogger(__name__)

#: What to install for this format (the one line of the error when it is missing).
INSTALL_HINT = 'pip install "bladetwin[ansys]"'


def _reader(path: Path):
    """``ansys.mapdl.reader``, imported lazily, for reading the existing file ``path``.

    A missing package gives a one-line error saying what to install; a missing file, ``FileNotFoundError``.
    """
    try:
        from ansys.mapdl import reader
    except ImportError:
        raise MissingDependencyError(f"{path}: reading ANSYS files needs the optional package ansys-mapdl-reader; "
                                     f"install it with: {INSTALL_HINT}") from None
    if not path.is_file():
        raise FileNotFoundError(2, "No such file or directory", str(path))
    return reader


def read_ansys_archive(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Nodes and node components of an ANSYS ``.cdb`` archive.

    Returns
    -------
    node_ids : ndarray of int64, shape (n,)
    coords : ndarray of float64, shape (n, 3)
        In the model's length unit.
    components : dict name → ndarray of int64
        Node ids of each named node component.
    """
    path = Path(path)
    reader = _reader(path)
    try:
        archive = reader.Archive(str(path))
        ids = np.asarray(archive.nnum, dtype=np.int64)
        xyz = np.asarray(archive.nodes, dtype=np.float64)[:, :3]
        comps = {str(k): np.asarray(v, dtype=np.int64).ravel() for k, v in archive.node_components.items()}
    except Exception as exc:  # the reader's compiled parser raises assorted types on a damaged archive
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ModelImportError(f"{path}: not a readable ANSYS archive ({why})") from None
    if ids.size == 0:
        raise ModelImportError(f"{path}: the archive has no nodes")
    return ids, xyz, comps


def read_ansys_full(
    path: str | os.PathLike,
    *,
    archive: str | os.PathLike | None = None,
    units: str | UnitSystem = "SI",
    name: str | None = None,
) -> Component:
    """Import an ANSYS ``.full`` file as a :class:`~rom.component.Component`.

    Parameters
    ----------
    path : path-like
        The ``.full`` file (symmetric K and M of a modal or substructuring run, consistent mass).
    archive : path-like, optional
        ``.cdb`` archive of the same model: node coordinates and named node components (as node sets).
    units : str or UnitSystem
        The model's unit system (see :mod:`rom.importers.units`); converted to SI.
    name : str, optional
        Component name (default: the file's stem).

    Returns
    -------
    Component
        In SI units; ``meta`` records the format, the units assumed and the constrained DOFs.
    """
    path = Path(path)
    reader = _reader(path)
    system = unit_system(units)
    try:
        full = reader.read_binary(str(path))
    except Exception as exc:  # damaged files surface as assorted exception types from the compiled reader
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ModelImportError(f"{path}: not a readable ANSYS file ({why})") from None
    if not hasattr(full, "load_km"):
        raise ModelImportError(f"{path}: this is an ANSYS {type(full).__name__}, not a .full matrix file")
    _check_header(path, getattr(full, "_header", {}))
    dof_ref, k, m = _load_km(path, full)
    layout = dof_layout(dof_ref[:, 0], dof_ref[:, 1] + 1, str(path))
    K, k_storage = matrix_to_csr(k, layout.n_dof, index=layout.index, where=str(path), label="K")
    del k
    M, m_storage = matrix_to_csr(m, layout.n_dof, index=layout.index, where=str(path), label="M")
    del m
    coords = None
    sets: dict[str, np.ndarray] = {}
    if archive is not None:
        ids, xyz, sets = read_ansys_archive(archive)
        coords = (ids, xyz)
        sets = _sets_inside(archive, sets, layout.node_ids)
    n_const = int(len(full.const)) if getattr(full, "const", None) is not None else 0
    meta = {"format": "full", "storage": f"K {k_storage}, M {m_storage}", "archive": str(archive) if archive else None,
            "ansys_constrained_dofs": n_const}
    return finish_component(name or path.stem, K, M, layout.node_ids, coords=coords, node_sets=sets, units=system,
                            source=str(path), meta=meta)


def _check_header(path: Path, header: dict) -> None:
    """Refuse a ``.full`` file whose header points past its end, or whose nodes do not carry UX, UY, UZ.

    The reader's compiled code reads past the end of a truncated file (it crashed the interpreter in a test):
    every block the header points to (4-byte words) must lie inside the file first.
    """
    size = path.stat().st_size
    ends = {k: 4 * int(header[k]) for k in ("ptrEND", "ptrSTF", "ptrMAS", "ptrDOF") if header.get(k)}
    if not ends or max(ends.values()) > size:
        far = max(ends, key=ends.get) if ends else "ptrEND"
        raise ModelImportError(f"{path}: truncated or damaged: the header's {far} points to byte {ends.get(far, '?')}, "
                               f"the file has {size} bytes")
    numdof = int(header.get("numdof", 3))
    if numdof != 3:
        raise ModelImportError(f"{path}: the model has {numdof} DOFs per node; only 3-D solids with UX, UY, UZ are "
                               "supported")


def _load_km(path: Path, full):
    """The DOF reference (node, 0-based direction) of shape (n, 2) and the reader's K and M, checked."""
    try:
        dof_ref, k, m = full.load_km(as_sparse=True, sort=False)
    except Exception as exc:  # a truncated file fails inside the compiled reader, with assorted types
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ModelImportError(f"{path}: could not read K and M ({why})") from None
    if k is None or m is None:
        raise ModelImportError(f"{path}: the file holds no {'stiffness' if k is None else 'mass'} matrix")
    dof_ref = np.asarray(dof_ref, dtype=np.int64)
    if dof_ref.ndim != 2 or dof_ref.shape[0] != k.shape[0] or (dof_ref[:, 1] > 2).any() or (dof_ref[:, 1] < 0).any():
        raise ModelImportError(f"{path}: unexpected DOF reference (shape {dof_ref.shape}); only UX, UY, UZ supported")
    return dof_ref, k, m


def _sets_inside(archive, sets: dict[str, np.ndarray], node_ids: np.ndarray) -> dict[str, np.ndarray]:
    """The node components lying wholly in this model: components may name nodes of other parts of the archive."""
    keep = {}
    for key, nodes in sets.items():
        inside = np.isin(nodes, node_ids)
        if inside.all():
            keep[key] = nodes
        else:
            log.info("%s: node component %r names %d node(s) outside the .full model; left out", archive, key,
                     int((~inside).sum()))
    return keep
