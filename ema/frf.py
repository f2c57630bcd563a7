"""Frequency response function sets: the in-memory form of measured FRFs.

An :class:`FRFSet` holds an FRF matrix of shape ``(n_outputs, n_inputs, n_freq)`` on a frequency axis in Hz,
the DOF labels of its responses (outputs) and references (inputs), its form (receptance, mobility or
accelerance) and unit labels. Transforms return new objects; nothing is modified in place.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import EMAError
from .units import UNIT_FACTORS, clean_label, parse_units, unit_factor

__all__ = [
    "FRF_FORMS",
    "UNIT_FACTORS",
    "DOF",
    "Nodes",
    "UnitSystem",
    "FRFSet",
    "check_dof",
    "convert_form",
    "line_ranges",
    "merge_frfsets",
    "parse_units",
    "unit_factor",
]

log = logging.getLogger(__name__)

#: Supported FRF forms and the power of ``j*omega`` that turns a receptance into them.
FRF_FORMS: dict[str, int] = {"receptance": 0, "mobility": 1, "accelerance": 2}

#: A DOF label: ``(node_id, direction)``; direction in ±1..±6 (UFF: 1..3 translations x, y, z,
#: 4..6 rotations; a negative sign means the negative axis) or 0 for a scalar.
DOF = tuple[int, int]


def check_dof(label: Sequence[int], what: str = "DOF label") -> DOF:
    """Validate and normalise one DOF label.

    Parameters
    ----------
    label : sequence of two ints
        ``(node_id, direction)``.
    what : str
        Name used in error messages.

    Returns
    -------
    tuple of (int, int)
    """
    if isinstance(label, str) or len(label) != 2:
        raise ValueError(f"{what} {label!r}: expected (node_id, direction)")
    try:
        node, direction = int(label[0]), int(label[1])
    except (TypeError, ValueError):
        raise ValueError(f"{what} {label!r}: expected (node_id, direction) as two integers") from None
    if not -6 <= direction <= 6:
        raise ValueError(f"{what} {label!r}: direction {direction} outside -6..6")
    return (node, direction)


@dataclass(frozen=True)
class Nodes:
    """Node coordinates read from UFF 15 or 2411.

    Attributes
    ----------
    ids : ndarray of int, shape (n_nodes,)
    xyz : ndarray of float, shape (n_nodes, 3)
        Coordinates in the file's length unit.
    """

    ids: np.ndarray
    xyz: np.ndarray

    def __post_init__(self) -> None:
        ids = np.asarray(self.ids, dtype=np.int64).reshape(-1)
        xyz = np.asarray(self.xyz, dtype=np.float64)
        if xyz.shape != (ids.size, 3):
            raise ValueError(f"Nodes: xyz has shape {xyz.shape}, expected ({ids.size}, 3)")
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "xyz", xyz)


@dataclass(frozen=True)
class UnitSystem:
    """Units from UFF 164.

    Attributes
    ----------
    code : int
        UFF units code (1 = SI: meter, newton, ...).
    description : str
    length, force, temperature : float
        Factors that convert the file's length / force / temperature unit to SI.
    """

    code: int
    description: str
    length: float
    force: float
    temperature: float


@dataclass(frozen=True)
class FRFSet:
    """A set of FRFs on one frequency axis.

    Attributes
    ----------
    freq_hz : ndarray of float64, shape (n_freq,)
        Strictly increasing frequency axis in Hz.
    H : ndarray of complex128, shape (n_outputs, n_inputs, n_freq)
        FRF matrix; ``H[o, i]`` is the response at ``outputs[o]`` to a unit excitation at ``inputs[i]``.
        The estimators refuse non-finite values, except on a 0 Hz line: there a free structure's receptance
        is infinite and :meth:`with_form` divides by zero, so a non-finite 0 Hz line is left out of fits.
    outputs : tuple of (int, int)
        Response DOF labels ``(node, direction)``, length n_outputs.
    inputs : tuple of (int, int)
        Reference (excitation) DOF labels, length n_inputs.
    form : {"receptance", "mobility", "accelerance"}
        Displacement, velocity or acceleration over force.
    units : str
        Free text unit label of the FRF values (e.g. ``"m/s^2/N"``); empty when unknown.
    nodes : Nodes or None
        Node coordinates when the source file carried them.
    unit_system : UnitSystem or None
        Units data set when the source file carried one.
    sources : tuple of str
        Files the set was read from (for messages only).
    """

    freq_hz: np.ndarray
    H: np.ndarray
    outputs: tuple[DOF, ...]
    inputs: tuple[DOF, ...]
    form: str = "receptance"
    units: str = ""
    nodes: Nodes | None = None
    unit_system: UnitSystem | None = None
    sources: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        freq = np.asarray(self.freq_hz, dtype=np.float64)
        H = np.asarray(self.H, dtype=np.complex128)
        if freq.ndim != 1 or freq.size < 2:
            raise ValueError(f"FRFSet: freq_hz must be 1-D with at least 2 lines, got shape {freq.shape}")
        if not np.all(np.isfinite(freq)) or np.any(np.diff(freq) <= 0):
            raise ValueError("FRFSet: freq_hz must be finite and strictly increasing")
        if freq[0] < 0:
            raise ValueError(f"FRFSet: freq_hz starts at {freq[0]} Hz, expected >= 0")
        if H.ndim != 3 or H.shape[2] != freq.size:
            raise ValueError(f"FRFSet: H has shape {H.shape}, expected (n_outputs, n_inputs, {freq.size})")
        outputs = tuple(check_dof(d, "output DOF") for d in self.outputs)
        inputs = tuple(check_dof(d, "input DOF") for d in self.inputs)
        if len(outputs) != H.shape[0] or len(inputs) != H.shape[1]:
            raise ValueError(
                f"FRFSet: {len(outputs)} output and {len(inputs)} input labels for H of shape {H.shape}"
            )
        if self.form not in FRF_FORMS:
            raise ValueError(f"FRFSet: form {self.form!r} not one of {sorted(FRF_FORMS)}")
        freq.setflags(write=False)
        H.setflags(write=False)
        object.__setattr__(self, "freq_hz", freq)
        object.__setattr__(self, "H", H)
        object.__setattr__(self, "outputs", outputs)
        object.__setattr__(self, "inputs", inputs)
        object.__setattr__(self, "sources", tuple(str(s) for s in self.sources))

    # ------------------------------------------------------------------ views
    @property
    def n_outputs(self) -> int:
        return self.H.shape[0]

    @property
    def n_inputs(self) -> int:
        return self.H.shape[1]

    @property
    def n_freq(self) -> int:
        return self.H.shape[2]

    @property
    def omega(self) -> np.ndarray:
        """Angular frequency axis in rad/s, shape (n_freq,)."""
        return 2.0 * np.pi * self.freq_hz

    def valid_lines(self) -> np.ndarray:
        """Boolean mask, shape (n_freq,), of lines where every FRF is finite."""
        return np.all(np.isfinite(self.H), axis=(0, 1))

    def flat(self) -> np.ndarray:
        """FRFs as rows, shape (n_outputs * n_inputs, n_freq), output-major (sdypy-EMA's layout)."""
        return self.H.reshape(self.n_outputs * self.n_inputs, self.n_freq)

    def mean_abs(self) -> np.ndarray:
        """Mean magnitude over all FRFs, shape (n_freq,); NaN lines stay NaN."""
        return np.mean(np.abs(self.H), axis=(0, 1))

    def cmif(self) -> np.ndarray:
        """Complex mode indicator function: singular values of H per line, shape (min(n_o, n_i), n_freq)."""
        Hf = np.moveaxis(self.H, 2, 0)
        out = np.full((Hf.shape[0], min(self.n_outputs, self.n_inputs)), np.nan)
        ok = self.valid_lines()
        out[ok] = np.linalg.svd(Hf[ok], compute_uv=False) ** 2
        return out.T

    # ------------------------------------------------------------- transforms
    def with_form(self, form: str) -> FRFSet:
        """The same FRFs in another form (receptance, mobility, accelerance).

        Multiplying by ``(j*omega)**k`` is exact; dividing at 0 Hz gives NaN on that line.
        """
        return replace(self, H=convert_form(self.H, self.freq_hz, self.form, form), form=form, units="")

    def band(self, f_lo: float, f_hi: float) -> FRFSet:
        """The lines with ``f_lo <= f <= f_hi`` (Hz)."""
        f_lo, f_hi = float(f_lo), float(f_hi)
        if not f_hi > f_lo:
            raise ValueError(f"band [{f_lo}, {f_hi}] Hz: upper limit must exceed the lower one")
        mask = (self.freq_hz >= f_lo) & (self.freq_hz <= f_hi)
        if mask.sum() < 2:
            raise ValueError(
                f"band [{f_lo}, {f_hi}] Hz holds {int(mask.sum())} lines of the axis "
                f"[{self.freq_hz[0]}, {self.freq_hz[-1]}] Hz; expected at least 2"
            )
        return replace(self, freq_hz=self.freq_hz[mask], H=self.H[:, :, mask])

    def select(self, outputs: Sequence[int] | None = None, inputs: Sequence[int] | None = None) -> FRFSet:
        """A subset of outputs and/or inputs by index."""
        o = list(range(self.n_outputs)) if outputs is None else [int(i) for i in outputs]
        i = list(range(self.n_inputs)) if inputs is None else [int(k) for k in inputs]
        return replace(
            self,
            H=self.H[np.ix_(o, i, np.arange(self.n_freq))],
            outputs=tuple(self.outputs[k] for k in o),
            inputs=tuple(self.inputs[k] for k in i),
        )


def convert_form(H: np.ndarray, freq_hz: np.ndarray, src: str, dst: str) -> np.ndarray:
    """Convert FRF values between receptance, mobility and accelerance.

    Parameters
    ----------
    H : ndarray, shape (..., n_freq)
    freq_hz : ndarray, shape (n_freq,)
        Frequency axis in Hz.
    src, dst : str
        Forms in :data:`FRF_FORMS`.

    Returns
    -------
    ndarray of complex128, shape like ``H``
        ``H * (j*omega)**(k_dst - k_src)``; lines where this divides by zero are NaN.
    """
    for name in (src, dst):
        if name not in FRF_FORMS:
            raise ValueError(f"FRF form {name!r} not one of {sorted(FRF_FORMS)}")
    k = FRF_FORMS[dst] - FRF_FORMS[src]
    H = np.asarray(H, dtype=np.complex128)
    if k == 0:
        return H.copy()
    jw = 1j * 2.0 * np.pi * np.asarray(freq_hz, dtype=np.float64)
    if k > 0:
        return H * jw**k
    factor = np.full(jw.shape, np.nan + 0j)
    nz = jw != 0
    factor[nz] = jw[nz] ** k
    return H * factor


def line_ranges(freq_hz: np.ndarray, mask: np.ndarray, max_runs: int = 3) -> str:
    """Describe the lines selected by ``mask`` as frequency ranges, for messages.

    Parameters
    ----------
    freq_hz : ndarray, shape (n_freq,)
    mask : ndarray of bool, shape (n_freq,)
    max_runs : int
        Runs of consecutive lines listed before the rest is summarised.

    Returns
    -------
    str
        E.g. ``"100 lines, 0.25-25 Hz"`` or ``"3 lines, 10 Hz, 20-20.5 Hz"``.
    """
    freq = np.asarray(freq_hz, dtype=np.float64)
    idx = np.flatnonzero(np.asarray(mask, dtype=bool))
    if idx.size == 0:
        return "no lines"
    starts = np.concatenate([[0], np.flatnonzero(np.diff(idx) > 1) + 1])
    ends = np.concatenate([starts[1:] - 1, [idx.size - 1]])
    runs = [
        f"{freq[idx[a]]:.6g} Hz" if a == b else f"{freq[idx[a]]:.6g}-{freq[idx[b]]:.6g} Hz"
        for a, b in zip(starts[:max_runs], ends[:max_runs], strict=True)
    ]
    more = f" and {starts.size - max_runs} more ranges" if starts.size > max_runs else ""
    return f"{idx.size} line{'s' if idx.size > 1 else ''}, " + ", ".join(runs) + more


def _same_axis(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> bool:
    if a.shape != b.shape:
        return False
    scale = max(float(np.max(np.abs(a))), 1e-300)
    return bool(np.all(np.abs(a - b) <= rtol * scale))


def _unit_mismatch(s: FRFSet, first: FRFSet) -> str | None:
    """Why the units of ``s`` cannot be converted into those of ``first`` (None when they can)."""
    a, b = clean_label(s.units), clean_label(first.units)
    if not a and not b:
        us, uf = s.unit_system, first.unit_system
        if us is not None and uf is not None and (us.length, us.force) != (uf.length, uf.force):
            return (f"no unit labels, and unit systems differ (length x{us.length:g}, force x{us.force:g} vs "
                    f"length x{uf.length:g}, force x{uf.force:g})")
        return None
    if not a or not b:
        return f"unit label {a!r} vs {b!r}: one file does not state its units"
    pa, pb = parse_units(a), parse_units(b)
    for label, parsed in ((a, pa), (b, pb)):
        if parsed is None:
            return f"units {a!r} vs {b!r}: {label!r} is not a unit label this reader can convert"
    assert pa is not None and pb is not None
    if pa[1] != pb[1]:
        return f"units {a!r} vs {b!r} are of different dimensions"
    return None


def merge_frfsets(sets: Sequence[FRFSet]) -> FRFSet:
    """Merge FRF sets measured on one structure into one matrix (roving hammer or roving response).

    The result's outputs and inputs are the union of the labels (in order of first appearance); every
    (output, input) pair must be measured exactly once. Values are converted into the units of the first
    set when another set states different but convertible units (``"mm/N"`` into ``"m/N"`` multiplies by
    1e-3; see :func:`unit_factor` and :data:`UNIT_FACTORS`).

    Parameters
    ----------
    sets : sequence of FRFSet
        Same frequency axis and FRF form.

    Returns
    -------
    FRFSet

    Raises
    ------
    EMAError
        Different frequency axes or forms, units that cannot be converted (unknown, missing on one side,
        or of another dimension), a pair measured twice, or a pair not measured at all. The message names
        the files involved.
    """
    sets = list(sets)
    if not sets:
        raise EMAError("merge_frfsets: no FRF sets given")
    first = sets[0]
    factors = _merge_factors(sets)
    outputs: list[DOF] = []
    inputs: list[DOF] = []
    for s in sets:
        outputs += [d for d in s.outputs if d not in outputs]
        inputs += [d for d in s.inputs if d not in inputs]
    nodes = next((s.nodes for s in sets if s.nodes is not None), None)
    units = next((s.unit_system for s in sets if s.unit_system is not None), None)
    return FRFSet(
        freq_hz=first.freq_hz,
        H=_merged_matrix(sets, factors, outputs, inputs),
        outputs=tuple(outputs),
        inputs=tuple(inputs),
        form=first.form,
        units=first.units,
        nodes=nodes,
        unit_system=units,
        sources=tuple(src for s in sets for src in s.sources),
    )


def _merge_factors(sets: list[FRFSet]) -> list[float]:
    """Each set's factor into the first set's units, once its axis, form and units are found to agree with it."""
    first = sets[0]
    first_name = ", ".join(first.sources) or "the first set"
    factors = [1.0]
    for s in sets[1:]:
        name = ", ".join(s.sources) or "a set"
        if not _same_axis(s.freq_hz, first.freq_hz):
            raise EMAError(
                f"merge: {name} has a frequency axis of {s.n_freq} lines [{s.freq_hz[0]}, {s.freq_hz[-1]}] Hz, "
                f"expected {first.n_freq} lines [{first.freq_hz[0]}, {first.freq_hz[-1]}] Hz"
            )
        if s.form != first.form:
            raise EMAError(f"merge: {name} is {s.form}, expected {first.form} as in {first_name}")
        why = _unit_mismatch(s, first)
        if why is not None:
            raise EMAError(f"merge: cannot combine {name} with {first_name}: {why}")
        factor = unit_factor(s.units, first.units) if (s.units or first.units) else 1.0
        assert factor is not None
        if factor != 1.0:
            log.info("merge: %s converted from %s to %s (x %.6g)", name, s.units, first.units, factor)
        factors.append(factor)
    return factors


def _merged_matrix(sets: list[FRFSet], factors: list[float], outputs: list[DOF], inputs: list[DOF]) -> np.ndarray:
    """The sets' FRFs (times their factors) on the merged layout; every (output, input) pair exactly once."""
    H = np.full((len(outputs), len(inputs), sets[0].n_freq), np.nan + 0j)
    filled = np.zeros((len(outputs), len(inputs)), dtype=bool)
    for s, factor in zip(sets, factors, strict=True):
        for a, out in enumerate(s.outputs):
            for b, inp in enumerate(s.inputs):
                o, i = outputs.index(out), inputs.index(inp)
                if filled[o, i]:
                    raise EMAError(f"merge: FRF {out} / {inp} is measured twice (again in {', '.join(s.sources)})")
                filled[o, i] = True
                H[o, i] = s.H[a, b] * factor
    if not filled.all():
        o, i = np.argwhere(~filled)[0]
        raise EMAError(
            f"merge: FRF {outputs[o]} / {inputs[i]} is missing ({int((~filled).sum())} of "
            f"{filled.size} pairs unmeasured); the merged set must be a full matrix"
        )
    return H
