"""One :class:`~rom.component.Component` from files: Matrix Market or OP4 matrices plus the CSV side files,
or an ANSYS ``.full`` file (:mod:`rom.importers.ansys`); :func:`import_component` picks by format.

Order of work, so that a large model is read once and never held twice: the DOF map and the coordinates
first (they fix the component's node list and where every matrix row goes), then K and M straight into
component numbering, then node sets, unit conversion and checks (:func:`rom.importers.build.finish_component`).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..component import Component
from .ansys import read_ansys_full
from .build import dof_layout, finish_component, matrix_to_csr
from .csvio import read_coords_csv, read_dofmap_csv, read_node_sets_csv
from .errors import ModelImportError
from .matrix_market import read_matrix_market, read_matrix_market_header
from .op4 import read_op4
from .units import UnitSystem, unit_system

__all__ = ["FORMATS", "guess_format", "read_matrix_market_component", "read_op4_component", "import_component"]

#: Importable formats: Matrix Market pair, Nastran OP4, ANSYS .full.
FORMATS = ("mtx", "op4", "full")

_SUFFIXES = {".mtx": "mtx", ".mm": "mtx", ".op4": "op4", ".full": "full"}


def guess_format(path: str | os.PathLike) -> str:
    """The format of a model file from its suffix (``.mtx``/``.mm``, ``.op4``, ``.full``)."""
    fmt = _SUFFIXES.get(Path(path).suffix.lower())
    if fmt is None:
        raise ModelImportError(f"{path}: cannot tell the format from the suffix {Path(path).suffix!r}; give it "
                               f"explicitly (one of {list(FORMATS)})")
    return fmt


def _side_files(dofmap, coords, node_sets, n_rows: int, where: Path):
    if dofmap is None:
        raise ModelImportError(f"{where}: a DOF map CSV (row,node,dir) is needed to place the matrix rows on nodes")
    nodes, dirs = read_dofmap_csv(dofmap, n_rows)
    xyz = read_coords_csv(coords) if coords is not None else None
    # The mesh is the coordinates file's nodes: one without any matrix row is fully constrained, and kept.
    layout = dof_layout(nodes, dirs, str(dofmap), extra_nodes=None if xyz is None else xyz[0])
    sets = read_node_sets_csv(node_sets) if node_sets is not None else {}
    return layout, xyz, sets


def read_matrix_market_component(
    K_path: str | os.PathLike,
    M_path: str | os.PathLike,
    *,
    dofmap: str | os.PathLike | None,
    coords: str | os.PathLike | None = None,
    node_sets: str | os.PathLike | None = None,
    units: str | UnitSystem = "SI",
    name: str | None = None,
) -> Component:
    """Import a component from a Matrix Market pair and its CSV side files.

    Parameters
    ----------
    K_path, M_path : path-like
        Stiffness and mass matrices (``coordinate real``, symmetric or general storage).
    dofmap : path-like
        ``row,node,dir`` for every matrix row (:mod:`rom.importers.csvio`).
    coords : path-like, optional
        ``node,x,y,z`` (without it the coordinates are NaN: no grids, no mass check).
    node_sets : path-like, optional
        ``set,node``.
    units : str or UnitSystem
        The files' unit system; converted to SI.
    name : str, optional
        Component name (default: the stem of ``K_path`` without a trailing ``_K``).
    """
    K_path, M_path = Path(K_path), Path(M_path)
    system = unit_system(units)
    hk = read_matrix_market_header(K_path)
    hm = read_matrix_market_header(M_path)
    if (hk.n_rows, hk.n_cols) != (hm.n_rows, hm.n_cols):
        raise ModelImportError(f"{M_path}: M is {hm.n_rows} × {hm.n_cols} but K ({K_path.name}) is "
                               f"{hk.n_rows} × {hk.n_cols}; they must have the same size")
    layout, xyz, sets = _side_files(dofmap, coords, node_sets, hk.n_rows, K_path)
    index = None if layout.is_identity else layout.index
    K, k_storage = read_matrix_market(K_path, index=index, n=layout.n_dof, label="K")
    M, m_storage = read_matrix_market(M_path, index=index, n=layout.n_dof, label="M")
    meta = {"format": "mtx", "files": [str(K_path), str(M_path)], "storage": f"K {k_storage}, M {m_storage}"}
    default = K_path.stem[:-2] if K_path.stem.lower().endswith("_k") else K_path.stem  # disk_K.mtx → "disk"
    return finish_component(name or default, K, M, layout.node_ids, coords=xyz, node_sets=sets, units=system,
                            source=str(K_path), meta=meta)


def read_op4_component(
    path: str | os.PathLike,
    *,
    dofmap: str | os.PathLike | None,
    coords: str | os.PathLike | None = None,
    node_sets: str | os.PathLike | None = None,
    matrices: tuple[str, str] | None = None,
    units: str | UnitSystem = "SI",
    name: str | None = None,
) -> Component:
    """Import a component from an OP4 file holding K and M, and its CSV side files.

    Parameters
    ----------
    path : path-like
        OP4 file (text or binary, real double precision).
    matrices : (str, str), optional
        Names of K and M in the file. Default: the one name starting with ``K`` and the one starting with
        ``M`` (e.g. ``KAA``, ``MAA``).
    dofmap, coords, node_sets, units, name
        As for :func:`read_matrix_market_component`.
    """
    path = Path(path)
    system = unit_system(units)
    mats = read_op4(path)
    if matrices is None:
        ks = [n for n in mats if n.upper().startswith("K")]
        ms = [n for n in mats if n.upper().startswith("M")]
        if len(ks) != 1 or len(ms) != 1:
            raise ModelImportError(f"{path}: cannot tell K and M apart among the matrices {list(mats)}; name them "
                                   "(e.g. matrices=('KAA', 'MAA'))")
        matrices = (ks[0], ms[0])
    for n in matrices:
        if n not in mats:
            raise ModelImportError(f"{path}: no matrix {n!r}; the file holds {list(mats)}")
    k, m = mats[matrices[0]].matrix, mats[matrices[1]].matrix
    if k.shape != m.shape:
        raise ModelImportError(f"{path}: M ({matrices[1]}) is {m.shape[0]} × {m.shape[1]} but K ({matrices[0]}) is "
                               f"{k.shape[0]} × {k.shape[1]}; they must have the same size")
    if k.shape[0] != k.shape[1]:
        raise ModelImportError(f"{path}: K ({matrices[0]}) must be square, got {k.shape[0]} × {k.shape[1]}")
    layout, xyz, sets = _side_files(dofmap, coords, node_sets, k.shape[0], path)
    index = None if layout.is_identity else layout.index
    K, k_storage = matrix_to_csr(k, layout.n_dof, index=index, where=str(path), label=f"K ({matrices[0]})")
    M, m_storage = matrix_to_csr(m, layout.n_dof, index=index, where=str(path), label=f"M ({matrices[1]})")
    del mats, k, m
    meta = {"format": "op4", "matrices": list(matrices), "storage": f"K {k_storage}, M {m_storage}"}
    return finish_component(name or path.stem, K, M, layout.node_ids, coords=xyz, node_sets=sets, units=system,
                            source=str(path), meta=meta)


def import_component(
    path: str | os.PathLike,
    *,
    format: str | None = None,
    mass: str | os.PathLike | None = None,
    dofmap: str | os.PathLike | None = None,
    coords: str | os.PathLike | None = None,
    node_sets: str | os.PathLike | None = None,
    archive: str | os.PathLike | None = None,
    matrices: tuple[str, str] | None = None,
    units: str | UnitSystem = "SI",
    name: str | None = None,
) -> Component:
    """Import one component in any supported format (the command line's ``--import``).

    Parameters
    ----------
    path : path-like
        ``.full`` file, OP4 file, or the Matrix Market file of K.
    format : {"mtx", "op4", "full"}, optional
        Default: from the suffix of ``path``.
    mass : path-like, optional
        Matrix Market file of M (``mtx`` only; required there).
    dofmap, coords, node_sets : path-like, optional
        CSV side files (``mtx`` and ``op4``; the DOF map is required there).
    archive : path-like, optional
        ``.cdb`` archive (``full`` only).
    matrices : (str, str), optional
        K and M names in an OP4 file.
    units : str or UnitSystem
    name : str, optional
    """
    fmt = guess_format(path) if format is None else format
    if fmt not in FORMATS:
        raise ModelImportError(f"format must be one of {list(FORMATS)}, got {fmt!r}")
    given = {"mass": mass, "dofmap": dofmap, "coords": coords, "node_sets": node_sets, "archive": archive,
             "matrices": matrices}
    allowed = {"mtx": {"mass", "dofmap", "coords", "node_sets"}, "op4": {"dofmap", "coords", "node_sets", "matrices"},
               "full": {"archive"}}[fmt]
    extra = sorted(k for k, v in given.items() if v is not None and k not in allowed)
    if extra:
        raise ModelImportError(f"{path}: {', '.join(extra)} do(es) not apply to the {fmt!r} format "
                               f"(it takes {', '.join(sorted(allowed))})")
    if fmt == "full":
        return read_ansys_full(path, archive=archive, units=units, name=name)
    if fmt == "op4":
        return read_op4_component(path, dofmap=dofmap, coords=coords, node_sets=node_sets, matrices=matrices,
                                  units=units, name=name)
    if mass is None:
        raise ModelImportError(f"{path}: a Matrix Market import needs the mass matrix file too (M)")
    return read_matrix_market_component(path, mass, dofmap=dofmap, coords=coords, node_sets=node_sets, units=units,
                                        name=name)
