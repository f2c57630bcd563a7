"""Modal models: identified (or imported) natural frequencies, damping ratios and mode shapes."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .frf import DOF, FRF_FORMS, check_dof
from .mode_quality import ModeQuality
from .mode_quality import mode_quality as _mode_quality

__all__ = ["ModalModel", "pole_from_modal", "modal_from_pole"]


def pole_from_modal(frequencies_hz: np.ndarray, damping_ratio: np.ndarray) -> np.ndarray:
    """Continuous-time poles ``lambda = -zeta*omega_n + j*omega_n*sqrt(1 - zeta**2)`` in rad/s.

    Parameters
    ----------
    frequencies_hz : array_like, shape (n,)
        Undamped natural frequencies in Hz.
    damping_ratio : array_like, shape (n,)
        Viscous damping ratios (0.01 = 1 %).

    Returns
    -------
    ndarray of complex128, shape (n,)
    """
    wn = 2.0 * np.pi * np.asarray(frequencies_hz, dtype=np.float64)
    z = np.asarray(damping_ratio, dtype=np.float64)
    return -z * wn + 1j * wn * np.sqrt(np.clip(1.0 - z**2, 0.0, None))


def modal_from_pole(pole: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency (Hz) and damping ratio of continuous-time poles (rad/s).

    Parameters
    ----------
    pole : array_like of complex, shape (n,)

    Returns
    -------
    frequencies_hz, damping_ratio : ndarray, shape (n,)
        ``|lambda| / 2 pi`` and ``-Re(lambda) / |lambda|``.
    """
    pole = np.asarray(pole, dtype=np.complex128)
    wn = np.abs(pole)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(wn > 0, -pole.real / np.where(wn > 0, wn, 1.0), 0.0)
    return wn / (2.0 * np.pi), zeta


@dataclass(frozen=True)
class ModalModel:
    """Modes on labelled DOFs.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_modes,)
        Undamped natural frequencies in Hz, ascending.
    damping_ratio : ndarray, shape (n_modes,)
        Viscous damping ratios.
    shapes : ndarray of complex128, shape (n_dof, n_modes)
        Mode shapes as columns. Mass-normalised when a driving point was measured
        (``scaling == "mass"``), otherwise unit-norm with the largest component real (``"unit"``).
    dofs : tuple of (int, int)
        DOF labels of the shape rows.
    quality : ndarray, shape (n_modes,) or None
        Selection quality score in [0, 1] (see :func:`ema.selection.select_auto`).
    residues : ndarray of complex128, shape (n_modes, n_outputs, n_inputs) or None
        LSFD residues ``A_r`` of the receptance model ``sum_r A_r/(jw - l_r) + conj(A_r)/(jw - conj(l_r))``.
    lower_residual, upper_residual : ndarray of complex128, shape (n_outputs, n_inputs) or None
        Receptance residual terms ``L/(jw)**2`` and ``U``.
    outputs, inputs : tuple of (int, int)
        Labels of the residue matrices (empty when there are no residues).
    form : str
        FRF form of the data the residues were fitted to (synthesis returns this form).
    band_hz : tuple of float or None
        Band the model was fitted on.
    method : str
        Pole estimator ("lscf", "lsrf", ...) or "" when imported.
    scaling : str
        "mass" or "unit".
    frequency_std_hz, damping_std : ndarray, shape (n_modes,) or None
        Standard deviation of each natural frequency (Hz) and damping ratio: the fit's linearised covariance
        (:func:`ema.uncertainty.pole_std`), for the frequency with the scatter over model orders added
        (:func:`ema.uncertainty.order_spread`); NaN where a mode's window is too short to tell.
    """

    frequencies_hz: np.ndarray
    damping_ratio: np.ndarray
    shapes: np.ndarray
    dofs: tuple[DOF, ...]
    quality: np.ndarray | None = None
    residues: np.ndarray | None = None
    lower_residual: np.ndarray | None = None
    upper_residual: np.ndarray | None = None
    outputs: tuple[DOF, ...] = field(default=())
    inputs: tuple[DOF, ...] = field(default=())
    form: str = "receptance"
    band_hz: tuple[float, float] | None = None
    method: str = ""
    scaling: str = "unit"
    frequency_std_hz: np.ndarray | None = None
    damping_std: np.ndarray | None = None

    def __post_init__(self) -> None:
        f = np.asarray(self.frequencies_hz, dtype=np.float64).reshape(-1)
        z = np.asarray(self.damping_ratio, dtype=np.float64).reshape(-1)
        phi = np.asarray(self.shapes, dtype=np.complex128)
        if phi.ndim == 1:
            phi = phi[:, None]
        if z.shape != f.shape:
            raise ValueError(f"ModalModel: {f.size} frequencies but {z.size} damping ratios")
        if phi.ndim != 2 or phi.shape[1] != f.size:
            raise ValueError(f"ModalModel: shapes have shape {phi.shape}, expected (n_dof, {f.size})")
        dofs = tuple(check_dof(d) for d in self.dofs)
        if len(dofs) != phi.shape[0]:
            raise ValueError(f"ModalModel: {len(dofs)} DOF labels for {phi.shape[0]} shape rows")
        if self.form not in FRF_FORMS:
            raise ValueError(f"ModalModel: form {self.form!r} not one of {sorted(FRF_FORMS)}")
        for arr in (f, z, phi):
            arr.setflags(write=False)
        object.__setattr__(self, "frequencies_hz", f)
        object.__setattr__(self, "damping_ratio", z)
        object.__setattr__(self, "shapes", phi)
        object.__setattr__(self, "dofs", dofs)
        if self.quality is not None:
            q = np.asarray(self.quality, dtype=np.float64).reshape(-1)
            if q.shape != f.shape:
                raise ValueError(f"ModalModel: {q.size} quality values for {f.size} modes")
            object.__setattr__(self, "quality", q)
        for name in ("frequency_std_hz", "damping_std"):
            if getattr(self, name) is not None:
                v = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1)
                if v.shape != f.shape:
                    raise ValueError(f"ModalModel: {v.size} values of {name} for {f.size} modes")
                v.setflags(write=False)
                object.__setattr__(self, name, v)
        if self.residues is not None:
            A = np.asarray(self.residues, dtype=np.complex128)
            if A.shape != (f.size, len(self.outputs), len(self.inputs)):
                raise ValueError(
                    f"ModalModel: residues have shape {A.shape}, expected ({f.size}, {len(self.outputs)}, "
                    f"{len(self.inputs)})"
                )
            object.__setattr__(self, "residues", A)
        object.__setattr__(self, "outputs", tuple(check_dof(d) for d in self.outputs))
        object.__setattr__(self, "inputs", tuple(check_dof(d) for d in self.inputs))

    @property
    def n_modes(self) -> int:
        return int(self.frequencies_hz.size)

    @property
    def poles(self) -> np.ndarray:
        """Continuous-time poles in rad/s, shape (n_modes,), positive imaginary part."""
        return pole_from_modal(self.frequencies_hz, self.damping_ratio)

    def take(self, index: np.ndarray | list[int]) -> ModalModel:
        """A model with the modes ``index`` (in that order)."""
        idx = np.asarray(index, dtype=int).reshape(-1)
        return replace(
            self,
            frequencies_hz=self.frequencies_hz[idx],
            damping_ratio=self.damping_ratio[idx],
            shapes=self.shapes[:, idx],
            quality=None if self.quality is None else self.quality[idx],
            residues=None if self.residues is None else self.residues[idx],
            frequency_std_hz=None if self.frequency_std_hz is None else self.frequency_std_hz[idx],
            damping_std=None if self.damping_std is None else self.damping_std[idx],
        )

    def sorted(self) -> ModalModel:
        """The model with modes in ascending frequency."""
        return self.take(np.argsort(self.frequencies_hz, kind="stable"))

    def as_records(self) -> list[dict]:
        """One dict per mode: ``frequency_hz``, ``damping_ratio``, and ``quality`` and the standard deviations
        (``frequency_std_hz``, ``damping_std``) when known, then the shape's complexity indicators ``mpc``,
        ``mpd_deg`` and ``mcf`` (:func:`ema.mode_quality.mode_quality`; NaN for an all-zero shape) (JSON-ready)."""
        mq = _mode_quality(self.shapes)
        out = []
        for m in range(self.n_modes):
            rec = {"frequency_hz": float(self.frequencies_hz[m]), "damping_ratio": float(self.damping_ratio[m])}
            if self.quality is not None:
                rec["quality"] = float(self.quality[m])
            if self.frequency_std_hz is not None:
                rec["frequency_std_hz"] = float(self.frequency_std_hz[m])
                rec["damping_std"] = float(self.damping_std[m]) if self.damping_std is not None else None
            rec |= {"mpc": float(mq.mpc[m]), "mpd_deg": float(mq.mpd_deg[m]), "mcf": float(mq.mcf[m])}
            out.append(rec)
        return out

    def mode_quality(self) -> ModeQuality:
        """MPC, MPD (°) and MCF of every shape: :func:`ema.mode_quality.mode_quality` of ``shapes``."""
        return _mode_quality(self.shapes)
