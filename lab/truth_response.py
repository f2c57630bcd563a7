"""The forced response's truth (issue 47): the truth twin's full-assembly modes, mistuned and tuned.

The mistuning amplification factor (AF) of a ROM (:mod:`rom.forced`, ``bladetwin/stages/response.py``) is the
largest blade peak of the mistuned full assembly over its tuned disk's peak. To judge it against the virtual
rig's own AF, a campaign's truth keeps both assemblies' modes at every blade measurement point,
mass-normalised, in ``truth/response_modes.npz``:

=========================  ==============  =========================================================
key                        shape           content
=========================  ==============  =========================================================
``frequencies_hz``         (n,)            the mistuned truth's (the specimen's) natural frequencies
``shapes``                 (n_rows, n)     its mass-normalised shapes at the blade points (m/√kg)
``blade_energy``           (n,)            the blades' share of each mode's kinetic energy
``tuned_frequencies_hz``   (n_t,)          the same of the tuned truth (:func:`tuned_twin`)
``tuned_shapes``           (n_rows, n_t)
``tuned_blade_energy``     (n_t,)
``labels``                 (n_rows, 3)     each row's (slot, point, direction), int64, the same for both
=========================  ==============  =========================================================

Both solves are the full-assembly test's (its contact state after re-seating, its mode count) and their
frequencies are on its day (``TruthTwin.day_factor("assembly")``); a temperature scales K alone, so the
mass-normalised shapes stay as solved. :func:`load_response_truth` gives each as a
:class:`rom.fe_assembly.AssemblyModes`, which :func:`rom.forced.blade_modes` takes as it takes a ROM's.

``bladetwin lab simulate`` writes the file with every campaign (the mistuned part is the assembly test's own
truth solve); :func:`add_response_truth` (``bladetwin lab response-truth``) adds it to a campaign written
before, rebuilding the twin from the campaign's command and checking it against ``truth.json``.
"""

from __future__ import annotations

import json
import tomllib
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rom.contact import ContactPattern
from rom.fe_assembly import AssemblyModes
from rom.fileio import atomic_path

from . import specimen
from .campaign_spec import CampaignSpec, assembly_solve_modes, campaign_twin
from .truth import BladeVariation, TruthTwin, assemble_truth, solve_truth, varied_blade

__all__ = [
    "RESPONSE_FILE",
    "ResponseTruth",
    "tuned_twin",
    "response_modes",
    "response_arrays",
    "write_response_truth",
    "load_response_truth",
    "add_response_truth",
]

#: The file's name in a campaign's ``truth/`` folder.
RESPONSE_FILE = "response_modes.npz"
#: Its arrays: per mode set (mistuned, then tuned), frequencies, shapes and blade energy; the rows' labels.
_KEYS = ("frequencies_hz", "shapes", "blade_energy", "tuned_frequencies_hz", "tuned_shapes", "tuned_blade_energy",
         "labels")
#: How closely a rebuilt twin's full-assembly frequencies must match ``truth.json`` (the solves are
#: deterministic, one MKL thread: a rebuild agrees to rounding; a different twin is off by far more).
CHECK_RTOL = 1e-7


@dataclass(frozen=True, eq=False)
class ResponseTruth:
    """The forced response's truth of a campaign (``truth/response_modes.npz``, :func:`load_response_truth`).

    Attributes
    ----------
    mistuned, tuned : AssemblyModes
        The specimen's full assembly and its tuned counterpart (:func:`tuned_twin`), each with
        ``frequencies_hz`` (n,) on the full-assembly test's day, mass-normalised ``meas_shapes`` (n_rows, n)
        at every blade measurement point, ``meas_labels`` ``("blade", slot, point, direction)`` (the same
        rows for both) and ``blade_energy`` (n,); ``rigid_shapes`` is None. :func:`rom.forced.blade_modes`
        takes either as it takes a ROM's modes.
    """

    mistuned: AssemblyModes
    tuned: AssemblyModes


def _majority(patterns: Sequence[ContactPattern]) -> ContactPattern:
    """Per node, contact where at least half the joints have it (both flanks)."""
    L = np.stack([p.L for p in patterns])
    R = np.stack([p.R for p in patterns])
    return ContactPattern(2 * L.sum(axis=0) >= len(patterns), 2 * R.sum(axis=0) >= len(patterns))


def _mean_variation(variations: Sequence[BladeVariation]) -> BladeVariation:
    """The blades' mean variation; a fillet where at least half the blades have one."""

    def mean(name: str) -> float:
        return float(np.mean([getattr(v, name) for v in variations]))

    return BladeVariation(thickness=mean("thickness"), chord=mean("chord"), span=mean("span"),
                          modulus=mean("modulus"), fillet=2 * sum(v.fillet for v in variations) >= len(variations),
                          fillet_scale=mean("fillet_scale"))


def tuned_twin(twin: TruthTwin) -> TruthTwin:
    """The truth twin made tuned: the specimen's own materials and test days, without its mistuning.

    The truth's counterpart of a ROM's tuned disk (``bladetwin/stages/response.py:tuned_node``: every joint
    with the films' mean pattern and every blade the blades' mean δ):

    * **blades**: every slot gets the same blade, made (``lab.truth.varied_blade``) from the mean of the
      blades' variations (thickness, chord, span, modulus and fillet size; a fillet where at least half the
      blades have one) with the specimen's materials: the mean blade, as the ROM's mean δ;
    * **disk**: the specimen's disk material without its sector scatter (which splits the doublets: a
      mistuning of the disk);
    * **contact**: every joint the per-node majority (at least half the joints) of the *assembly-state*
      patterns (the contact the full-assembly test saw, after re-seating), in both states: the binary pattern
      nearest the joints' mean, as the ROM's baseline; each node's contact-stiffness factor the mean over the
      joints (``None`` stays ``None``);
    * ``materials``, ``day_factors`` and ``params`` (contact law, bolts) are kept: they act on every sector
      alike.

    Every sector is then the same, so the tuned truth's modes are cyclic: a blade-mode family's nodal
    diameters 1..N/2−1 come in degenerate pairs.
    """
    n = twin.n_blades
    variation = _mean_variation(twin.variations)
    blade = varied_blade(twin.bd, variation, twin.params, "blade_tuned", twin.materials)
    disk = specimen.truth_disk(twin.bd, twin.materials.get("disk_E", 0.0), twin.materials.get("disk_rho", 0.0),
                               None)
    pattern = _majority(twin.patterns_of("assembly"))
    scale = twin.contact_scale
    if scale is not None:
        scale = np.broadcast_to(np.mean(scale, axis=0), scale.shape).copy()
    return replace(twin, blades=(blade,) * n, variations=(variation,) * n, patterns=(pattern,) * n,
                   assembly_patterns=(pattern,) * n, disk=disk, sector_moduli=None, contact_scale=scale)


def _solve_assembly(twin: TruthTwin, n_modes: int) -> AssemblyModes:
    """The full assembly's truth solve in the full-assembly test's contact state (before its day factor)."""
    return solve_truth(assemble_truth(twin, None, state="assembly"), n_modes)


def _blade_rows(modes: AssemblyModes) -> tuple[list[int], np.ndarray]:
    rows = [k for k, lab in enumerate(modes.meas_labels) if lab[0] == "blade"]
    labels = np.array([[int(v) for v in modes.meas_labels[k][1:]] for k in rows], dtype=np.int64).reshape(-1, 3)
    return rows, labels


def response_arrays(mistuned: AssemblyModes, tuned: AssemblyModes, day_factor: float) -> dict[str, np.ndarray]:
    """The arrays of ``truth/response_modes.npz`` from two full-assembly truth solves (module docstring).

    Parameters
    ----------
    mistuned, tuned : AssemblyModes
        :func:`lab.truth.solve_truth` of the full assembly and of its :func:`tuned_twin` (every slot mounted),
        frequencies before the day factor.
    day_factor : float
        The full-assembly test's day (``TruthTwin.day_factor("assembly")``).
    """
    rows, labels = _blade_rows(mistuned)
    tuned_rows, tuned_labels = _blade_rows(tuned)
    if not np.array_equal(labels, tuned_labels) or not labels.size:
        raise ValueError("the mistuned and tuned truth solves measure different blade points")
    out = {}
    for prefix, modes, r in (("", mistuned, rows), ("tuned_", tuned, tuned_rows)):
        out[f"{prefix}frequencies_hz"] = np.asarray(modes.frequencies_hz, dtype=np.float64) * day_factor
        out[f"{prefix}shapes"] = np.asarray(modes.meas_shapes, dtype=np.float64)[r]
        out[f"{prefix}blade_energy"] = np.asarray(modes.blade_energy, dtype=np.float64)
    out["labels"] = labels
    return out


def response_modes(twin: TruthTwin, n_modes: int, *, mistuned: AssemblyModes | None = None) -> dict[str, np.ndarray]:
    """The mistuned and the tuned truth's full-assembly modes at the blade points (module docstring's arrays).

    Parameters
    ----------
    twin : TruthTwin
    n_modes : int
        Modes of each solve: the campaign's full-assembly test's (``lab.campaign_spec.assembly_solve_modes``).
    mistuned : AssemblyModes, optional
        The twin's full-assembly solve where already made (``n_modes`` modes, before the day factor); else
        solved here.

    Returns
    -------
    dict
        ``frequencies_hz`` (n,), ``shapes`` (n_rows, n), ``blade_energy`` (n,), the same with ``tuned_``, and
        ``labels`` int64 (n_rows, 3): (slot, point, direction) of each blade row.
    """
    if mistuned is None:
        mistuned = _solve_assembly(twin, n_modes)
    tuned = _solve_assembly(tuned_twin(twin), n_modes)
    return response_arrays(mistuned, tuned, twin.day_factor("assembly"))


def _check_rebuilt(frequencies_hz: np.ndarray, check_hz: Sequence[float]) -> None:
    """Raise ValueError unless the rebuilt frequencies inside [min, max] of ``check_hz`` are ``check_hz``."""
    want = np.sort(np.asarray(check_hz, dtype=np.float64).ravel())
    if not want.size or not np.all(np.isfinite(want)):
        raise ValueError("the truth's full-assembly frequencies to check against are empty or not finite")
    f = np.sort(np.asarray(frequencies_hz, dtype=np.float64))
    # The rebuilt modes from the one nearest the truth's first on: a rebuilt twin has the same modes in the span,
    # and a different one shows how far off it is (or that it has fewer modes there).
    first = int(np.argmin(np.abs(f - want[0]))) if f.size else 0
    got = f[first:first + want.size]
    if got.size != want.size:
        raise ValueError(f"the twin could not be rebuilt: {got.size} of its full-assembly modes lie from "
                         f"{want[0]:.6g} Hz on, the truth has {want.size} in {want[0]:.6g}..{want[-1]:.6g} Hz")
    err = np.max(np.abs(got / want - 1))
    if err > CHECK_RTOL:
        raise ValueError(f"the twin could not be rebuilt: its full-assembly frequencies differ from the truth's by "
                         f"up to {err:.2g} (relative; allowed {CHECK_RTOL:g})")


def write_response_truth(twin: TruthTwin, truth_dir: str | Path, n_modes: int,
                         check_hz: Sequence[float] | None = None, *, mistuned: AssemblyModes | None = None,
                         progress: Callable[[str], None] | None = None) -> Path:
    """Solve :func:`response_modes` and write ``truth_dir/response_modes.npz`` (atomically: nothing half-written).

    Parameters
    ----------
    twin : TruthTwin
    truth_dir : path
        The campaign's ``truth/`` folder.
    n_modes : int
        Modes of each solve (the full-assembly test's).
    check_hz : sequence of float, optional
        ``truth.json``'s ``all_frequencies_hz["assembly"]``: the mistuned solve's frequencies in their span must
        agree with it to 1e-7 (relative), checked before the tuned solve.
    mistuned : AssemblyModes, optional
        The twin's full-assembly solve where already made (before the day factor).
    progress : callable, optional
        Called with a short message before each solve.

    Raises
    ------
    ValueError
        If the rebuilt twin fails the check (nothing is written).
    """
    say = progress or (lambda msg: None)
    if mistuned is None:
        say(f"mistuned truth: full-assembly solve ({n_modes} modes)")
        mistuned = _solve_assembly(twin, n_modes)
    if check_hz is not None:
        _check_rebuilt(np.asarray(mistuned.frequencies_hz) * twin.day_factor("assembly"), check_hz)
        say("the rebuilt twin's full-assembly frequencies agree with truth.json")
    say(f"tuned truth: full-assembly solve ({n_modes} modes)")
    arrays = response_modes(twin, n_modes, mistuned=mistuned)
    path = Path(truth_dir) / RESPONSE_FILE
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    return path


def _modes(path: Path, f: np.ndarray, shapes: np.ndarray, energy: np.ndarray, labels: list, what: str
           ) -> AssemblyModes:
    if f.ndim != 1 or not f.size or energy.shape != f.shape or shapes.shape != (len(labels), f.size):
        raise ValueError(f"{path}: {what} frequencies {f.shape}, shapes {shapes.shape}, blade energy {energy.shape} "
                         f"do not fit {len(labels)} blade rows")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(shapes)) and np.all(np.isfinite(energy))):
        raise ValueError(f"{path}: {what} modes hold values that are not finite")
    if np.any(f <= 0) or np.any(np.diff(f) < 0):
        raise ValueError(f"{path}: {what} frequencies are not positive and ascending")
    return AssemblyModes(f, shapes, labels, None, energy)


def load_response_truth(truth_dir: str | Path) -> ResponseTruth | None:
    """The forced response's truth of a campaign's ``truth/`` folder; None where it has no ``response_modes.npz``.

    Raises
    ------
    ValueError
        Naming the file, where it is damaged or its arrays do not fit together (nothing is half-read).
    """
    path = Path(truth_dir) / RESPONSE_FILE
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in _KEYS if k not in z.files]
            if missing:
                raise ValueError(f"{path}: not a response truth file (no {', '.join(missing)})")
            raw = {k: np.array(z[k]) for k in _KEYS}
    except ValueError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise ValueError(f"{path}: unreadable response truth file ({exc})") from None
    except (OSError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"{path}: unreadable response truth file ({exc})") from None
    labels = raw.pop("labels")
    if labels.ndim != 2 or labels.shape[1] != 3 or not labels.shape[0] or not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"{path}: labels {labels.shape} ({labels.dtype}): expected integers, shape (n_rows, 3)")
    if np.any(labels[:, :2] < 1) or np.any((labels[:, 2] < 1) | (labels[:, 2] > 3)):
        raise ValueError(f"{path}: labels hold a slot or point below 1, or a direction outside 1..3")
    for k, a in raw.items():
        if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
            raise ValueError(f"{path}: {k} has dtype {a.dtype}; expected numbers")
    arr = {k: a.astype(np.float64) for k, a in raw.items()}
    meas_labels = [("blade", int(s), int(p), int(d)) for s, p, d in labels]
    mistuned = _modes(path, arr["frequencies_hz"], arr["shapes"], arr["blade_energy"], meas_labels, "mistuned")
    tuned = _modes(path, arr["tuned_frequencies_hz"], arr["tuned_shapes"], arr["tuned_blade_energy"],
                   list(meas_labels), "tuned")
    return ResponseTruth(mistuned, tuned)


def add_response_truth(campaign_dir: str | Path, progress: Callable[[str], None] | None = None, *,
                       spec_of: Callable[[str], CampaignSpec]) -> Path:
    """Add ``truth/response_modes.npz`` to a virtual campaign written before it existed.

    The twin is rebuilt from the campaign's ``[campaign] generated_by`` command
    (:func:`lab.campaign_spec.campaign_twin`, the same streams as the campaign's), and its full-assembly frequencies
    are checked against ``truth/truth.json`` before the tuned solve.

    Parameters
    ----------
    campaign_dir : path
        A campaign folder of ``bladetwin lab simulate`` (``campaign.toml``, ``truth/truth.json``).
    progress : callable, optional
        Called with a short message before each step.
    spec_of : callable
        Turns the ``bladetwin lab simulate ...`` command into its :class:`lab.campaign_spec.CampaignSpec`
        (``bladetwin.cli_lab.spec_from_command``: the command line's own parser; ``lab`` never imports
        ``bladetwin``).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ValueError
        One line: no campaign, no command (or one with settings made in Python), no full-assembly truth, a
        command that does not match the truth, or a twin that could not be rebuilt.
    """

    say = progress or (lambda msg: None)
    root = Path(campaign_dir)
    manifest = root / "campaign.toml"
    if not manifest.is_file():
        raise ValueError(f"{root}: no campaign.toml; expected a campaign folder written by `bladetwin lab simulate`")
    try:
        doc = tomllib.loads(manifest.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{manifest}: unreadable manifest ({exc})") from None
    command = (doc.get("campaign") or {}).get("generated_by")
    if not isinstance(command, str) or not command.strip():
        raise ValueError(f"{manifest}: no [campaign] generated_by command; only a campaign of `bladetwin lab "
                         "simulate` can have its twin rebuilt")
    if "settings made in Python" in command:
        raise ValueError(f"{manifest}: the campaign was made with settings made in Python; its twin cannot be "
                         "rebuilt from its command")
    truth_json = root / "truth" / "truth.json"
    try:
        truth = json.loads(truth_json.read_text(encoding="utf-8"))
        check_hz = truth["all_frequencies_hz"]["assembly"]
    except FileNotFoundError:
        raise ValueError(f"{truth_json}: missing; only a virtual campaign has a truth to add to") from None
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"{truth_json}: no full-assembly truth frequencies ({exc})") from None
    if not check_hz:
        raise ValueError(f"{truth_json}: the campaign has no full-assembly test")
    spec = spec_of(command)
    params = spec.model_params()
    found = {"seed": spec.seed, "n_blades": params.n_blades, "grid": list(params.grid)}
    wrong = {k: (truth.get(k), v) for k, v in found.items() if truth.get(k) != v}
    if wrong:
        raise ValueError(f"{manifest}: its command does not match {truth_json} ("
                         + ", ".join(f"{k} {a} there, {b} here" for k, (a, b) in wrong.items()) + ")")
    built = campaign_twin(spec, params, say)
    return write_response_truth(built.twin, root / "truth", assembly_solve_modes(params.n_blades), check_hz,
                                progress=say)
