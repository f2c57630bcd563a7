"""Import memory benchmark: peak RSS of importing a 2 M-DOF Matrix Market K, M pair (issue 13, docs/importers.md).

The pair is synthesized here and never stored in the repository: a 3-D hexahedral grid of nodes with three
DOFs each (node-major), K = L ⊗ I₃ with L the 7-point grid Laplacian shifted to be positive definite, and
M = (4 I + ½ A) ⊗ I₃ with A the grid adjacency (a consistent-mass-like pattern, diagonally dominant). Both
are written as ``coordinate real symmetric`` Matrix Market files (lower triangle) with a DOF map and node
coordinates, as a lab's export would be.

Each import runs in a fresh subprocess, so its peak RSS (``VmHWM`` of ``/proc/self/status``, Linux) is its own:

* **ours** — :func:`rom.importers.read_matrix_market_component` (streaming parser, DOF map, coordinates, SI
  conversion, checks), checked against checksums of the synthesized matrices;
* **reference** — ``scipy.io.mmread`` of the same two files, each converted to CSR (what a direct use of SciPy
  would do before any DOF mapping).

The figure is the peak RSS over the size of the final sparse matrices (CSR data + indices + indptr of K and
M); target < 3×. The baseline (interpreter, NumPy, SciPy, pandas imported) is reported apart.

Run (about two minutes, ~1 GB of temporary files)::

    .venv/bin/python benchmarks/import_memory.py [--nodes 88 88 87] [--workdir DIR] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _paths  # noqa: F401  (puts the repository first on sys.path)
import numpy as np
import scipy.sparse as sp

TARGET = 3.0

_CHILD = r"""
import json, sys, time, warnings
import numpy as np
kind, kp, mp, dofmap, coords, probe = sys.argv[1:7]
import scipy.io, scipy.sparse
from rom.importers import UnitsWarning, read_matrix_market_component
def rss():
    # VmHWM: the peak RSS of this process's own address space. ru_maxrss would not do: Linux carries the
    # parent's peak into a forked child (signal_struct.maxrss survives fork and exec).
    with open("/proc/self/status") as fh:
        return next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmHWM:"))
base = rss()
t = time.perf_counter()
if kind == "ours":
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitsWarning)  # a Laplacian is no steel part
        comp = read_matrix_market_component(kp, mp, dofmap=dofmap, coords=coords)
    K, M = comp.K, comp.M
else:
    K = scipy.io.mmread(kp).tocsr()
    M = scipy.io.mmread(mp).tocsr()
secs = time.perf_counter() - t
x = np.load(probe, allow_pickle=False)
size = sum(a.nbytes for A in (K, M) for a in (A.data, A.indices, A.indptr))
print(json.dumps({"peak_bytes": rss(), "baseline_bytes": base, "seconds": secs, "csr_bytes": size,
                  "nnz": [int(K.nnz), int(M.nnz)], "checks": [float(x @ (K @ x)), float(x @ (M @ x))]}))
"""


def synthesize(nodes: tuple[int, int, int]) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
    """K, M (node-major, 3 DOFs per node) and node coordinates of a hexahedral grid of ``nodes`` nodes."""
    nx, ny, nz = nodes

    def path(n: int) -> sp.csr_matrix:
        return sp.diags([np.ones(n - 1), np.ones(n - 1)], [-1, 1], format="csr")

    ix, iy, iz = (sp.identity(n, format="csr") for n in nodes)
    adj = (sp.kron(sp.kron(path(nx), iy), iz) + sp.kron(sp.kron(ix, path(ny)), iz)
           + sp.kron(sp.kron(ix, iy), path(nz))).tocsr()
    n = adj.shape[0]
    lap = (sp.identity(n) * 6.01 - adj).tocsr()  # SPD: strictly diagonally dominant
    mass = (sp.identity(n) * 4.0 + 0.5 * adj).tocsr()
    i3 = sp.identity(3, format="csr")
    K = sp.kron(lap * 1e8, i3, format="csr")
    M = sp.kron(mass * 1e-3, i3, format="csr")
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), axis=-1).reshape(-1, 3)
    return K, M, g * 1e-3


def run_child(kind: str, files: dict, probe: Path) -> dict:
    cmd = [sys.executable, "-c", _CHILD, kind, str(files["K"]), str(files["M"]), str(files["dofmap"]),
           str(files["coords"]), str(probe)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd=_paths.REPO)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nodes", type=int, nargs=3, default=[88, 88, 87], metavar=("NX", "NY", "NZ"),
                    help="grid of nodes (default 88 88 87: 2 021 184 DOFs)")
    ap.add_argument("--workdir", default=None, help="folder for the temporary files (default: a temporary folder)")
    ap.add_argument("--skip-reference", action="store_true", help="do not run the scipy.io.mmread reference")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    args = ap.parse_args(argv)

    from rom.importers.csvio import write_coords_csv, write_dofmap_csv
    from rom.importers.matrix_market import write_matrix_market

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    with tempfile.TemporaryDirectory(prefix="import_memory_", dir=args.workdir) as tmp:
        d = Path(tmp)
        t = time.perf_counter()
        K, M, X = synthesize(tuple(args.nodes))
        n = K.shape[0]
        ids = np.arange(1, X.shape[0] + 1)
        x = np.sin(np.arange(n) * 0.37)  # probe vector: xᵀ K x and xᵀ M x check the imported matrices
        expected = [float(x @ (K @ x)), float(x @ (M @ x))]
        nnz = [int(K.nnz), int(M.nnz)]
        files = {"K": d / "K.mtx", "M": d / "M.mtx", "dofmap": d / "dofmap.csv", "coords": d / "coords.csv"}
        write_matrix_market(files["K"], K, symmetry="symmetric")
        write_matrix_market(files["M"], M, symmetry="symmetric")
        write_dofmap_csv(files["dofmap"], np.repeat(ids, 3), np.tile([1, 2, 3], ids.size))
        write_coords_csv(files["coords"], ids, X)
        np.save(d / "probe.npy", x)
        del K, M, X
        file_mb = {k: v.stat().st_size / 1e6 for k, v in files.items()}
        say(f"synthesized and wrote {n:,} DOFs, nnz K {nnz[0]:,}, M {nnz[1]:,} in {time.perf_counter() - t:.0f} s "
            f"({sum(file_mb.values()):.0f} MB of files)")

        results = {}
        for kind in ("ours",) if args.skip_reference else ("ours", "reference"):
            say(f"importing ({kind}) in a fresh process …")
            r = run_child(kind, files, d / "probe.npy")
            ok = r["nnz"] == nnz and np.allclose(r["checks"], expected, rtol=1e-12, atol=0)
            r["matches_synthesized"] = bool(ok)
            r["ratio"] = r["peak_bytes"] / r["csr_bytes"]
            r["ratio_above_baseline"] = (r["peak_bytes"] - r["baseline_bytes"]) / r["csr_bytes"]
            results[kind] = r

    ours = results["ours"]
    gb = 1024**3
    print(f"{n:,} DOFs; K {nnz[0]:,} and M {nnz[1]:,} non-zeros; final CSR K + M {ours['csr_bytes'] / gb:.3f} GB")
    print(f"{'':<30s}{'peak RSS':>10s}{'baseline':>10s}{'time':>8s}{'peak / CSR':>12s}{'(− baseline)':>14s}"
          f"{'correct':>9s}")
    for kind, label in (("ours", "rom.importers (streaming)"), ("reference", "scipy.io.mmread + tocsr")):
        if kind not in results:
            continue
        r = results[kind]
        print(f"{label:<30s}{r['peak_bytes'] / gb:>8.2f} GB{r['baseline_bytes'] / gb:>7.2f} GB{r['seconds']:>7.1f}s"
              f"{r['ratio']:>11.2f}×{r['ratio_above_baseline']:>13.2f}×{str(r['matches_synthesized']):>9s}")
    if "reference" in results:
        print(f"side by side: ours / reference peak = {ours['peak_bytes'] / results['reference']['peak_bytes']:.2f}")
    print(f"target: peak < {TARGET:g}× the sparse matrices: {'met' if ours['ratio'] < TARGET else 'NOT met'} "
          f"({ours['ratio']:.2f}×)")
    if args.json:
        from rom.fileio import atomic_path

        out = {"n_dof": n, "nnz": nnz, "files_mb": file_mb, "target_ratio": TARGET, **results}
        with atomic_path(args.json) as tmp, open(tmp, "w") as fh:
            json.dump(out, fh, indent=2)
    return 0 if ours["ratio"] < TARGET and ours["matches_synthesized"] else 1


if __name__ == "__main__":
    sys.exit(main())
