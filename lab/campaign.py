"""A virtual measurement campaign on disk (issue 9, items 5–6): UFF files, film scans, manifest and truth.

Layout of ``<out>/`` (``NN`` 1-based, two digits; the manifest format is documented in docs/campaign.md):

```
campaign.toml                 manifest: tests, films, known joints, grid, model
blades/blade_NN.uff           free blade NN (3 leading-edge points)
disk/disk.uff                 free disk (1 axial point per sector)
d1b/joint_NN.uff              disk + blade NN in slot NN
assembly/assembly.uff         the full bladed disk
films/joint_NN_L.png, _R.png  film scans of the known joints
truth/truth.json              what the identification never sees (seed, deltas, exact frequencies, damping and
                              the damping each test's exponential window added)
truth/patterns.npz            true contact grids L, R: bool, shape (n_blades, rows, cols), in the state the
                              films and the disk–one-blade tests saw
truth/assembly_patterns.npz   the same after the blades were re-seated, in the full-assembly test
truth/assembly_modes.npz      the full assembly's visible modes: frequencies_hz (n,), exact real shapes at
                              the test's outputs (n_outputs, n), the blades' share of each mode's kinetic
                              energy (n,), and the outputs' (node, direction), (n_outputs, 2)
truth/response_modes.npz      the forced response's truth (lab.truth_response): every mode of the full
                              assembly's truth solve, mistuned and tuned (its tuned counterpart), mass-normalised
                              at every blade measurement point, on the assembly test's day
truth/films/                  every flank's film scan
```

The campaign is written into a temporary folder beside ``out`` and renamed into place at the end, so a
failed or interrupted run never leaves a half-written campaign.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import tomli_w

from ema.uff import write_frfs
from rom.academic import AcademicParams
from rom.fe_assembly import AssemblyModes
from rom.solver import nodal_diameters

from .campaign_spec import (
    BLADE_MODES,
    D1B_MODES,
    DISK_MODES,
    FULL_FAMILIES,
    TEST_TYPES,
    CampaignSpec,
    CampaignTwin,
    assembly_solve_modes,
    campaign_twin,
    default_known_joints,
    solved_modes,
)
from .documents import blade_deltas_pct, jsonable, specimen_truth, weighed
from .films import ORIENTATION, render_film, write_film
from .hammer import hammer_test
from .rig import MIN_SNR, RigSetup, canonical_degenerate, damping_ratios, measure, peak_snr
from .truth import (
    assemble_truth,
    solve_truth,
)
from .truth_response import write_response_truth

__all__ = ["CampaignSpec", "CampaignInfo", "CampaignTwin", "TEST_TYPES", "assembly_solve_modes", "campaign_twin",
           "default_known_joints", "simulate_campaign"]

#: Hammer references of the full-assembly test (blade tips spread round the disk). Mistuned modes localise
#: on a few blades; with 3 references the shapes of the modes far from all three were the EMA's weakest.
FULL_INPUTS = 6

#: FilmMeta fields kept out of the manifest: the misregistration applied to the film is truth.
TRUTH_ONLY_FILM_KEYS = ("shift", "rotation")


#: The truth twin the forked workers of :func:`solve_parallel` read (set just before the pool is forked, so
#: the children share it copy-on-write instead of receiving a pickled copy of the FE model).
_TWIN = None


def _solve_one(job: tuple) -> tuple:
    return _solve_one_with(_TWIN, *job)


def _solve_one_with(twin, slots, with_disk: bool, n: int, state: str = "d1b") -> tuple:
    """(measurement labels, truth modes) of one test's assembly, in contact ``state`` ("d1b" or "assembly")."""
    asm = assemble_truth(twin, slots, with_disk=with_disk, state=state)
    return asm.meas_labels, solve_truth(asm, n)


def solve_parallel(twin, jobs: list[tuple], workers: int) -> list[tuple]:
    """Truth solves of independent tests, ``workers`` at a time (each with one MKL thread, as always).

    The solves are bitwise the same as one by one (each runs single-threaded); only the wall time changes.
    Falls back to one by one where ``fork`` is not available.
    """
    global _TWIN
    _TWIN = twin
    try:
        if workers < 2 or "fork" not in multiprocessing.get_all_start_methods():
            return [_solve_one(j) for j in jobs]
        with multiprocessing.get_context("fork").Pool(workers) as pool:
            return pool.map(_solve_one, jobs, chunksize=1)
    finally:
        _TWIN = None


@dataclass(frozen=True)
class CampaignInfo:
    """What :func:`simulate_campaign` wrote."""

    campaign: Path
    n_files: int
    truth: Path

    def to_dict(self) -> dict:
        return {"campaign": str(self.campaign), "n_files": self.n_files, "truth": str(self.truth)}


def _setup(f_first: float, f_last: float, max_lines: int, f_modes: np.ndarray | None = None) -> RigSetup:
    """Band from half the first to 1.05 × the last mode of interest, on at most ``max_lines`` lines.

    The spacing is a multiple of 0.05 Hz: the coarsest that fits the band into ``max_lines``, refined (within
    that budget, as a lab zooms to split close modes) to a quarter of the closest spacing of ``f_modes``.
    """
    lo, hi = 0.5 * f_first, 1.05 * f_last
    step = 0.05
    coarsest = step * np.ceil((hi - lo) / (max_lines - 1) / step)
    df = max(coarsest, 0.25)
    if f_modes is not None and len(f_modes) > 1:
        f_modes = np.sort(f_modes)
        gaps = np.diff(f_modes)
        # Degenerate pairs (a tuned disk's nodal diameters) are one peak at any resolution: skip them.
        gaps = gaps[gaps > 1e-5 * f_modes[1:]]
        if gaps.size:
            df = max(coarsest, min(df, step * np.floor(gaps.min() / 4 / step)))
    df = float(max(df, step))
    # Lines on multiples of df: UFF 58's header then rebuilds the axis exactly, and the file need not carry
    # every abscissa (8 more bytes a line).
    return RigSetup((df * np.floor(lo / df), hi), df)


def _nn(k: int) -> str:
    return f"{k:02d}"


def simulate_campaign(
    spec: CampaignSpec, out: str | Path, progress: Callable[[str], None] | None = None
) -> CampaignInfo:
    """Simulate a whole campaign on the truth twin and write it to ``out`` (replacing nothing half-way).

    Parameters
    ----------
    spec : CampaignSpec
    out : path
        Campaign folder; must not exist yet, or be an empty folder.
    progress : callable, optional
        Called with a short message before each step.
    """
    say = progress or (lambda msg: None)
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"{out}: exists and is not an empty folder; choose a new --out")
    params = spec.model_params()
    known = spec.known()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes it 0700; the campaign is an ordinary folder
        n_files = _write(spec, params, known, tmp, say, out)
        if out.exists():
            out.rmdir()
        tmp.rename(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return CampaignInfo(out, n_files, out / "truth" / "truth.json")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _write(spec: CampaignSpec, params: AcademicParams, known: tuple[int, ...], root: Path, say, out: Path) -> int:
    """Simulate the campaign into ``root`` (renamed ``out`` when done): every test, the film scans, the manifest
    and the truth files."""
    writer = _CampaignWriter(spec, params, known, root, say, out)
    writer.component_tests()
    writer.assembly_test()
    writer.films()
    return writer.finish()


#: The per-test truth entries, each a mapping {"blades": [...], "disk": ..., "d1b": [...], "assembly": ...}.
_TRUTH_TEST_KEYS = ("frequencies_hz", "damping_ratios", "window_damping", "apparent_frequencies_hz",
                    "all_frequencies_hz", "all_apparent_frequencies_hz", "band_hz")


def _blade_tip(labels) -> list[int]:
    return [k for k, lab in enumerate(labels) if lab[0] == "blade" and lab[2] == 3][:1]


def _disk_first(labels) -> list[int]:
    return [k for k, lab in enumerate(labels) if lab[0] == "disk"][:1]


def _spread_tips(labels) -> list[int]:
    # Hammer on the tips of FULL_INPUTS blades spread round the disk: mistuned modes localise on a few
    # blades, and one reference would miss the rest.
    tips = [k for k, lab in enumerate(labels) if lab[0] == "blade" and lab[2] == 3]
    pick = np.round(np.linspace(0, len(tips), FULL_INPUTS, endpoint=False)).astype(int)
    # fewer tips than references (a 2-blade disk): the last rounds up to len(tips), one past the end
    return [tips[i] for i in np.unique(np.minimum(pick, len(tips) - 1))]


class _CampaignWriter:
    """One campaign being written into ``root``: the truth twin, its random streams, and the manifest and truth
    documents as the tests and films fill them in (always in the same order, so a seed gives the same files)."""

    def __init__(self, spec: CampaignSpec, params: AcademicParams, known: tuple[int, ...], root: Path, say,
                 out: Path):
        self.spec, self.params, self.known, self.root, self.say = spec, params, known, root, say
        built = campaign_twin(spec, params, say)
        self.rng_damping, self.rng_noise, self.rng_film = built.rng_damping, built.rng_noise, built.rng_film
        self.pressure, self.patterns, self.twin = built.pressure, built.patterns, built.twin
        self.truth_params = spec.truth_params()
        scale = built.disk_scale
        self.manifest: dict = {
            "campaign": {"name": spec.name, "kind": "virtual", "n_blades": params.n_blades, "grid": list(params.grid),
                         "known_joints": list(known), "generated_by": spec.command(out),
                         # what every UFF of the rig holds; `bladetwin run` checks each file against it
                         "frf_units": "m/s/N"},
            # disk_scale only where the disk was enlarged to hold the blades (rom.academic.disk_scale_for)
            "model": {"family": "academic", "level": params.level, "n_blades": params.n_blades,
                      "grid": list(params.grid), **({"disk_scale": scale} if scale != 1.0 else {})},
            "tests": [],
            "films": [],
            "masses": weighed(self.twin),
        }
        pressure = self.pressure
        self.truth: dict = {"seed": spec.seed, "n_blades": params.n_blades, "grid": list(params.grid),
                            "known_joints": list(known), "realism": spec.realism, "reseated_joints": list(spec.reseat),
                            "truth_params": jsonable(self.truth_params), **specimen_truth(self.twin),
                            "blade_variations": [v.to_dict() for v in self.twin.variations],
                            "contact_fraction_pct": {"L": (100 * pressure.fractions[:, 0]).tolist(),
                                                     "R": (100 * pressure.fractions[:, 1]).tolist()}}
        for key in _TRUTH_TEST_KEYS:
            self.truth[key] = {"blades": [], "disk": None, "d1b": [], "assembly": None}
        self.n_files = 0
        self.assembly_modes: dict | None = None
        self.assembly_solve: AssemblyModes | None = None  # the full assembly's truth solve, before the day factor
        self.presolved: dict = {}
        self.workers = max(1, min(2, os.cpu_count() or 1))

    def run_test(self, kind: str, rel: str, slots, with_disk: bool, n_wanted: int, inputs_of,
                 families: int = 0) -> dict:
        """One test; ``families`` > 0: the band covers that many blade-mode families (n_blades modes each)."""
        max_lines = self.spec.max_lines[kind]
        # Compute past the modes of interest (solved_modes): invisible (in-plane) modes interleave with them, and the
        # modes above the band leave their residual effect at its upper edge.
        key = (kind, tuple(slots) if slots is not None else None)
        if key in self.presolved:
            meas_labels, modes = self.presolved.pop(key)
        else:
            meas_labels, modes = _solve_one_with(self.twin, slots, with_disk, solved_modes(n_wanted),
                                                 "assembly" if kind == "assembly" else "d1b")
        if kind == "assembly":  # the mistuned truth of truth/response_modes.npz (finish): no second solve
            self.assembly_solve = modes
        # The test day's temperature scales every frequency of that day (1 on the ideal twin).
        modes = replace(modes, frequencies_hz=modes.frequencies_hz * self.twin.day_factor(kind))
        if not with_disk:
            # A free blade's points carry the same labels on every blade (nodes 1..3): one test rig, many blades.
            modes = replace(modes, meas_labels=[("blade", 0, p, d) for _, _, p, d in modes.meas_labels])
        outputs = list(range(len(meas_labels)))
        inputs = inputs_of(meas_labels)
        modes = canonical_degenerate(modes, inputs)
        f = modes.frequencies_hz
        zeta = damping_ratios(f.size, self.rng_damping, self.truth_params.damping_range)
        # Band from the modes a test can see: first a generous one, then the first n_wanted visible modes.
        snr = peak_snr(modes, zeta, _setup(f[0], f[-1], max_lines), outputs, inputs)
        seen = np.flatnonzero(snr >= MIN_SNR)
        if families:
            blade_modes = np.flatnonzero(modes.blade_energy > 0.5)
            last = blade_modes[min(families * self.params.n_blades, blade_modes.size) - 1]
            seen = seen[f[seen] <= f[last]]
        else:
            seen = seen[:n_wanted]
        setup = _setup(f[seen[0]], f[seen[-1]], max_lines, f[seen])
        frf, window = self.measure(kind, rel, modes, zeta, setup, inputs, outputs)
        lo, hi = setup.band_hz
        snr = peak_snr(modes, zeta, setup, outputs, inputs)
        in_band = (f >= lo) & (f <= hi)
        visible = np.flatnonzero(in_band & (snr >= MIN_SNR))
        # The exponential window moves each pole left by 1/τ, so the natural frequency the data hold is
        # f √(1 + 2ζΔζ + Δζ²): about 1e-6 relative, a few standard deviations of a full-assembly EMA.
        apparent = f * np.sqrt(1.0 + 2.0 * zeta * window + window**2)
        result = {"frequencies_hz": f[visible].tolist(), "damping_ratios": zeta[visible].tolist(),
                  "window_damping": window[visible].tolist(), "apparent_frequencies_hz": apparent[visible].tolist(),
                  "all_frequencies_hz": f[in_band].tolist(), "all_apparent_frequencies_hz": apparent[in_band].tolist(),
                  "band_hz": [lo, hi]}
        if kind == "assembly":  # the exact shapes, to judge the EMA's (truth only: no fit ever reads them)
            self.assembly_modes = {"frequencies_hz": f[visible], "shapes": modes.meas_shapes[:, visible],
                                   "blade_energy": modes.blade_energy[visible],
                                   "outputs": np.array(frf.outputs, dtype=np.int64).reshape(-1, 2)}
        if kind == "disk":
            disk_rows = [k for k, lab in enumerate(meas_labels) if lab[0] == "disk"]
            result["nodal_diameters"] = nodal_diameters(modes.meas_shapes[disk_rows][:, visible]).tolist()
        return result

    def measure(self, kind: str, rel: str, modes, zeta: np.ndarray, setup: RigSetup, inputs: list[int],
                outputs: list[int]) -> tuple:
        """Write one test's UFF file: (its FRFs, the damping its exponential window adds to each mode, 0
        without one).

        The realistic twin runs the time-domain hammer test and exports its coherence beside the FRFs; the
        ideal twin adds noise to the exact FRFs in the frequency domain (:func:`lab.rig.measure`).
        """
        hammer = self.truth_params.hammer
        coherence = None
        if hammer is None:
            frf = measure(modes, zeta, setup, self.rng_noise, inputs, outputs)
            window = np.zeros(modes.frequencies_hz.size)
        else:
            test = hammer_test(modes, zeta, setup, self.rng_noise, inputs, outputs, hammer.for_band(setup.band_hz[1]))
            frf, window = test.frf, test.window_damping
            coherence = test.coherence if kind in self.spec.coherence else None
        write_frfs(self.root / rel, frf, id1=f"bladetwin lab {kind}", precision="single", coherence=coherence)
        self.n_files += 1
        return frf, window

    def tip_and_disk(self, labels) -> list[int]:
        """The blade tip, and the disk point of the next sector: a disk mode whose nodal line runs through the
        blade's slot barely moves the blade, and a second hammer off that line excites it."""
        tip = _blade_tip(labels)
        slot = labels[tip[0]][1]
        sector = slot % self.params.n_blades + 1
        return tip + [k for k, lab in enumerate(labels) if lab[0] == "disk" and lab[1] == sector][:1]

    def record(self, group: str, result: dict) -> None:
        """Add one test's result to the truth entries of its group (a list per blade or joint, else one value)."""
        for key in _TRUTH_TEST_KEYS:
            if isinstance(self.truth[key][group], list):
                self.truth[key][group].append(result[key])
            else:
                self.truth[key][group] = result[key]

    def per_slot(self, kind: str, group: str, folder: str, stem: str, key: str, with_disk: bool,
                 n_wanted: int) -> None:
        """One test per slot: the free blades, or each blade in its own slot of the disk (d1b)."""
        for s in range(1, self.params.n_blades + 1):
            self.say(f"{kind} {s}/{self.params.n_blades}")
            rel = f"{folder}/{stem}_{_nn(s)}.uff"
            self.record(group, self.run_test(kind, rel, [s], with_disk, n_wanted,
                                             self.tip_and_disk if with_disk else _blade_tip))
            self.manifest["tests"].append({"type": kind, "file": rel, key: s})

    def component_tests(self) -> None:
        """The free blades, the free disk and each disk–one-blade test."""
        n_blades = self.params.n_blades
        self.per_slot("blade", "blades", "blades", "blade", "blade", False, BLADE_MODES)
        self.say("free disk")
        disk = self.run_test("disk", "disk/disk.uff", (), True, DISK_MODES, _disk_first)
        self.record("disk", disk)
        self.truth["disk_nodal_diameters"] = disk["nodal_diameters"]
        self.manifest["tests"].append({"type": "disk", "file": "disk/disk.uff"})
        # The disk–one-blade truth solves dominate the build and are independent: solve them two at a time first
        # (the measurements that follow draw their random numbers in the same order as ever).
        self.say(f"d1b truth solves ({n_blades}, {self.workers} at a time)")
        jobs = [([s], True, solved_modes(D1B_MODES)) for s in range(1, n_blades + 1)]
        for (slots, _, _), result in zip(jobs, solve_parallel(self.twin, jobs, self.workers), strict=True):
            self.presolved[("d1b", tuple(slots))] = result
        self.per_slot("d1b", "d1b", "d1b", "joint", "joint", True, D1B_MODES)

    def assembly_test(self) -> None:
        """The full bladed disk, then the blades' frequency deviations (truth)."""
        self.say("full bladed disk")
        n_full = FULL_FAMILIES * self.params.n_blades + DISK_MODES
        self.record("assembly", self.run_test("assembly", "assembly/assembly.uff", None, True, n_full, _spread_tips,
                                              families=FULL_FAMILIES))
        # no max_order hint: the EMA's families fit finds the order from the data (docs/ema.md)
        self.manifest["tests"].append({"type": "assembly", "file": "assembly/assembly.uff"})
        self.truth["blade_deltas_pct"] = blade_deltas_pct(self.truth["frequencies_hz"]["blades"])

    def films(self) -> None:
        """Every flank's film scan into ``truth/films/``; the known joints' also into ``films/``."""
        self.say("film scans")
        for s in range(1, self.params.n_blades + 1):
            for flank in ("L", "R"):
                image, meta = render_film(self.pressure, s, flank, self.rng_film, self.spec.film)
                name = f"joint_{_nn(s)}_{flank}.png"
                write_film(self.root / "truth" / "films" / name, image)
                entry = {"joint": s, "flank": flank, "file": f"films/{name}", **jsonable(meta.to_dict())}
                if s in self.known:
                    write_film(self.root / "films" / name, image)
                    self.n_files += 1
                    # The misregistration actually applied is truth (diagnostics only): a lab's manifest can't
                    # know it.
                    self.manifest["films"].append({k: v for k, v in entry.items() if k not in TRUTH_ONLY_FILM_KEYS})
                self.truth.setdefault("films", []).append({**entry, "file": f"truth/films/{name}"})

    def finish(self) -> int:
        """Write the true patterns, the full assembly's truth modes (``assembly_modes.npz``,
        ``response_modes.npz``), ``truth.json`` and ``campaign.toml``; the number of campaign files written."""
        self.manifest["campaign"]["orientation"] = ORIENTATION
        L = np.stack([p.L for p in self.patterns])
        R = np.stack([p.R for p in self.patterns])
        with open(self.root / "truth" / "patterns.npz", "wb") as fh:
            np.savez_compressed(fh, L=L, R=R)
        seated = self.twin.patterns_of("assembly")
        with open(self.root / "truth" / "assembly_patterns.npz", "wb") as fh:
            np.savez_compressed(fh, L=np.stack([p.L for p in seated]), R=np.stack([p.R for p in seated]))
        if self.assembly_modes is not None:
            with open(self.root / "truth" / "assembly_modes.npz", "wb") as fh:
                np.savez_compressed(fh, **self.assembly_modes)
        if self.assembly_solve is not None:
            # The forced response's truth: the mistuned solve the test made, and the tuned truth's (one solve).
            write_response_truth(self.twin, self.root / "truth", assembly_solve_modes(self.params.n_blades),
                                 mistuned=self.assembly_solve, progress=self.say)
        (self.root / "truth" / "truth.json").write_text(json.dumps(self.truth, indent=1), encoding="utf-8")
        (self.root / "campaign.toml").write_text(tomli_w.dumps(self.manifest), encoding="utf-8")
        return self.n_files
