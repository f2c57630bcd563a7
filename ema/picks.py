"""Picks files: a hand pole selection saved as a small JSON file and applied again to the same UFF file.

A :class:`Picks` holds what :func:`ema.fit` needs to rebuild the stabilization diagram the picks were made
on (method, band, highest order, number of sub-bands) and the picks themselves as ``(order, frequency_hz)``
pairs. :func:`save_picks` writes it (atomically), :func:`load_picks` reads it back and refuses a damaged
file with a one-line :class:`~ema.errors.EMAError` that names the file and the field, and
:func:`fit_with_picks` fits the FRFs with those picks instead of the automatic selection.

The file (``"format": "bladetwin-picks"``, ``"version": 1``)::

    {
      "format": "bladetwin-picks",
      "version": 1,
      "file": "blades/blade_03.uff",
      "method": "lsrf",
      "band_hz": [50.0, 980.0],
      "max_order": 40,
      "n_bands": 1,
      "note": "close pair at 240 Hz picked by hand",
      "picks": [
        {"order": 40, "frequency_hz": 120.00731},
        {"order": 40, "frequency_hz": 240.01544}
      ]
    }

This module imports no plotting library: :func:`picks_from_picker` only reads ``picker.picks``.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .dominance import mode_dominance
from .errors import EMAError
from .fileio import atomic_path
from .fit import EMAResult, fit
from .frf import FRFSet
from .global_fit import METHODS
from .lsfd import fit_quality, modal_model
from .settings import FitSettings

if TYPE_CHECKING:  # pragma: no cover - typing only; ema.picker imports matplotlib
    from .picker import PolePicker

__all__ = ["FORMAT", "VERSION", "Picks", "save_picks", "load_picks", "picks_from_picker", "fit_with_picks"]

#: Format tag of a picks file.
FORMAT = "bladetwin-picks"
#: Version of the picks file format written (and the only one read).
VERSION = 1

_REQUIRED = ("file", "method", "band_hz", "max_order", "picks")
_OPTIONAL = {"n_bands": 1, "note": ""}
_KNOWN = frozenset(("format", "version", *_REQUIRED, *_OPTIONAL))
_PICK_KEYS = ("order", "frequency_hz")


def _short(value: Any, limit: int = 40) -> str:
    """A value on one line, as JSON writes it (else ``repr``), cut to about ``limit`` characters."""
    try:  # JSON spelling (a file's values are JSON): true, null, "text", [1, 2]
        text = json.dumps(list(value) if isinstance(value, tuple) else value)
    except (TypeError, ValueError, RecursionError):
        text = repr(value)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


@dataclass(frozen=True)
class Picks:
    """A hand pole selection for one UFF file, with the fit settings of the diagram it was made on.

    Attributes
    ----------
    file : str
        The UFF file the picks belong to, as given (usually relative to the campaign folder). It is
        recorded, not resolved: :func:`fit_with_picks` fits whatever FRFs it is given.
    method : {"lsrf", "lscf"}
        Pole estimator of the diagram.
    band_hz : (float, float) or None
        Band of the fit, ``0 < f_lo < f_hi``; None: all lines.
    max_order : int
        Highest model order of the diagram (>= 2).
    picks : tuple of (int, float)
        ``(order, frequency_hz)`` of each picked pole (:attr:`ema.picker.PolePicker.picks`): order a
        positive integer, frequency positive and finite, inside ``band_hz`` when a band is given; at least
        one pick, no pick twice.
    n_bands : int
        Number of sub-bands of the fit (>= 1; > 1: band-by-band, orders are the local orders).
    note : str
        Free text (who picked, why).

    Raises
    ------
    EMAError
        A field of the wrong type or value; the message starts with the field's name.
    """

    file: str
    method: str
    band_hz: tuple[float, float] | None
    max_order: int
    picks: tuple[tuple[int, float], ...]
    n_bands: int = 1
    note: str = ""

    def __post_init__(self) -> None:
        file = self.file
        if isinstance(file, os.PathLike):
            file = os.fspath(file)
        if not isinstance(file, str) or not file.strip():
            raise EMAError(f"file {_short(file)}: expected the UFF file name (a non-empty string)")
        if not isinstance(self.method, str) or self.method not in METHODS:
            raise EMAError(f"method {_short(self.method)}: expected one of {', '.join(sorted(METHODS))}")
        band = self.band_hz
        if band is not None:
            if isinstance(band, str | bytes) or not isinstance(band, Sequence | np.ndarray) or len(band) != 2:
                raise EMAError(f"band_hz {_short(band)}: expected [f_lo, f_hi] in Hz or null")
            if not all(_is_real(b) for b in band):
                raise EMAError(f"band_hz {_short(band)}: expected two numbers (Hz)")
            band = (float(band[0]), float(band[1]))
            if not (math.isfinite(band[0]) and math.isfinite(band[1]) and 0 < band[0] < band[1]):
                raise EMAError(f"band_hz {_short(band)}: expected 0 < f_lo < f_hi, finite")
        if not _is_int(self.max_order) or self.max_order < 2:
            raise EMAError(f"max_order {_short(self.max_order)}: expected an integer >= 2")
        if not _is_int(self.n_bands) or self.n_bands < 1:
            raise EMAError(f"n_bands {_short(self.n_bands)}: expected an integer >= 1")
        if not isinstance(self.note, str):
            raise EMAError(f"note {_short(self.note)}: expected a string")
        picks = self.picks
        if isinstance(picks, str | bytes) or not isinstance(picks, Sequence | np.ndarray):
            raise EMAError(f"picks {_short(picks)}: expected a list of (order, frequency_hz)")
        if len(picks) == 0:
            raise EMAError("picks: none given (at least one pick needed)")
        clean: list[tuple[int, float]] = []
        for k, pick in enumerate(picks):
            if isinstance(pick, str | bytes) or not isinstance(pick, Sequence | np.ndarray) or len(pick) != 2:
                raise EMAError(f"picks[{k}] {_short(pick)}: expected (order, frequency_hz)")
            order, freq = pick
            if not _is_int(order) or order < 1:
                raise EMAError(f"picks[{k}].order {_short(order)}: expected a positive integer")
            if not _is_real(freq):
                raise EMAError(f"picks[{k}].frequencies_hz {_short(freq)}: expected a number (Hz)")
            try:
                f = float(freq)
            except OverflowError:
                f = math.inf
            if not (math.isfinite(f) and f > 0):
                raise EMAError(f"picks[{k}].frequencies_hz {_short(freq)}: expected a positive, finite frequency (Hz)")
            if band is not None and not band[0] <= f <= band[1]:
                raise EMAError(
                    f"picks[{k}] ({int(order)}, {f:g} Hz): frequency outside band_hz {band[0]:g}-{band[1]:g} Hz"
                )
            if (int(order), f) in clean:
                raise EMAError(f"picks[{k}] ({int(order)}, {f:g} Hz): picked twice")
            clean.append((int(order), f))
        object.__setattr__(self, "file", file)
        object.__setattr__(self, "band_hz", band)
        object.__setattr__(self, "max_order", int(self.max_order))
        object.__setattr__(self, "n_bands", int(self.n_bands))
        object.__setattr__(self, "picks", tuple(clean))

    def as_dict(self) -> dict[str, Any]:
        """The JSON document of the picks file (format tag and version included)."""
        return {
            "format": FORMAT,
            "version": VERSION,
            "file": self.file,
            "method": self.method,
            "band_hz": None if self.band_hz is None else list(self.band_hz),
            "max_order": self.max_order,
            "n_bands": self.n_bands,
            "note": self.note,
            "picks": [{"order": o, "frequency_hz": f} for o, f in self.picks],
        }


def save_picks(path: str | os.PathLike, picks: Picks) -> Path:
    """Write a picks file (JSON, one pick a line), atomically.

    Parameters
    ----------
    path : str or path-like
        Target file; its folder is created if needed. Conventionally ``picks/<test>.json`` in the
        campaign folder.
    picks : Picks

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    EMAError
        The file cannot be written (e.g. ``path`` is a folder).
    """
    if not isinstance(picks, Picks):
        raise TypeError(f"save_picks: expected a Picks, got {type(picks).__name__}")
    doc = picks.as_dict()
    items = doc.pop("picks")
    lines = [f"  {json.dumps(key)}: {json.dumps(value, allow_nan=False)}," for key, value in doc.items()]
    lines.append('  "picks": [')
    lines.append(",\n".join(f"    {json.dumps(item, allow_nan=False)}" for item in items))
    lines.append("  ]")
    text = "{\n" + "\n".join(lines) + "\n}\n"
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise EMAError(f"{path}: cannot write the picks file ({exc.strerror or exc})") from None
    return path


def load_picks(path: str | os.PathLike) -> Picks:
    """Read a picks file written by :func:`save_picks` (or by hand in the same format).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    Picks

    Raises
    ------
    EMAError
        One line naming the file and the field at fault: a missing or unreadable file, not JSON, a wrong
        ``format`` tag or ``version``, a missing, unknown or mistyped field, or a bad value.
    """
    where = str(path)

    def refuse(reason: str) -> EMAError:
        return EMAError(f"{where}: {reason}")

    try:
        raw = Path(path).read_bytes()
    except IsADirectoryError:
        raise refuse("is a folder, not a picks file") from None
    except FileNotFoundError:
        raise refuse("picks file not found") from None
    except OSError as exc:
        raise refuse(f"cannot read the picks file ({exc.strerror or exc})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise refuse("not a picks file (not UTF-8 text)") from None
    if not text.strip():
        raise refuse("empty file, not a picks file")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise refuse(f"not a picks file: not JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    except RecursionError:
        raise refuse("not a picks file: JSON nested too deeply") from None
    if not isinstance(data, dict):
        raise refuse(f"not a picks file: expected a JSON object, got {type(data).__name__}")
    if "format" not in data:
        raise refuse(f"not a picks file: field format missing (expected \"{FORMAT}\")")
    if data["format"] != FORMAT:
        raise refuse(f"not a picks file: field format is {_short(data['format'])}, expected \"{FORMAT}\"")
    version = data.get("version")
    if "version" not in data:
        raise refuse("field version missing")
    if not _is_int(version) or version != VERSION:
        raise refuse(f"field version {_short(version)}: unsupported (this version reads {VERSION})")
    unknown = sorted(set(data) - _KNOWN)
    if unknown:
        raise refuse(f"unknown field(s) {', '.join(_short(k) for k in unknown)}")
    missing = [key for key in _REQUIRED if key not in data]
    if missing:
        raise refuse(f"missing field(s) {', '.join(missing)}")
    items = data["picks"]
    if not isinstance(items, list):
        raise refuse(f"field picks {_short(items)}: expected a list of {{\"order\", \"frequency_hz\"}} objects")
    pairs = []
    for k, item in enumerate(items):
        if not isinstance(item, dict):
            raise refuse(f"field picks[{k}] {_short(item)}: expected an object {{\"order\", \"frequency_hz\"}}")
        absent = [key for key in _PICK_KEYS if key not in item]
        extra = sorted(set(item) - set(_PICK_KEYS))
        if absent:
            raise refuse(f"field picks[{k}]: missing {', '.join(absent)}")
        if extra:
            raise refuse(f"field picks[{k}]: unknown field(s) {', '.join(_short(e) for e in extra)}")
        pairs.append((item["order"], item["frequency_hz"]))
    kwargs = {key: data.get(key, default) for key, default in _OPTIONAL.items()}
    try:
        return Picks(file=data["file"], method=data["method"], band_hz=data["band_hz"],
                     max_order=data["max_order"], picks=tuple(pairs), **kwargs)
    except EMAError as exc:
        raise refuse(f"field {exc}") from None


def picks_from_picker(
    picker: PolePicker,
    file: str,
    method: str,
    band_hz: tuple[float, float] | None,
    max_order: int,
    n_bands: int = 1,
    note: str = "",
) -> Picks:
    """The current picks of a :class:`~ema.picker.PolePicker` as a :class:`Picks`.

    Parameters
    ----------
    picker : PolePicker
        Anything with a ``picks`` attribute of ``(order, frequency_hz)`` pairs.
    file : str
        The UFF file the diagram was fitted from, as the campaign names it.
    method, band_hz, max_order, n_bands :
        The settings the picker's diagram was made with (those :func:`fit_with_picks` passes to
        :func:`ema.fit`).
    note : str

    Returns
    -------
    Picks
    """
    return Picks(file=file, method=method, band_hz=band_hz, max_order=max_order, picks=tuple(picker.picks),
                 n_bands=n_bands, note=note)


def fit_with_picks(frf: FRFSet, picks: Picks, freq_tol: float = 0.01, elsewhere: dict | None = None) -> EMAResult:
    """Fit FRFs with the hand picks of a picks file instead of the automatic selection.

    Calls ``ema.fit(frf, picks.band_hz, FitSettings(method=picks.method, n_bands=picks.n_bands),
    max_order=picks.max_order, picks=list(picks.picks))``: the diagram is computed again and each pick takes
    the pole of its order nearest in frequency (:func:`ema.selection.select_picks`). Picked modes are never
    dropped by the dominance filter.

    Parameters
    ----------
    frf : FRFSet
        The FRFs of ``picks.file``.
    picks : Picks
    freq_tol : float
        Largest relative distance between a pick and the pole it takes (the picks come from a diagram
        of the same data, so they should match to rounding; 1 % leaves room for another machine's BLAS).
    elsewhere : dict, optional
        Where the picks' band is narrower than the FRFs' lines (picks of one mode family), the modes outside it
        come from the automatic ``ema.fit(frf, **elsewhere)``, e.g. ``{"families": True}``; all modes then
        share one LSFD over the automatic fit's band, each keeping its own shape and standard deviations.
        None: the picked band's modes only.

    Returns
    -------
    EMAResult
        With one mode per pick (and, with ``elsewhere``, the automatic fit's modes outside the picks' band; the
        diagram is then the automatic fit's).

    Raises
    ------
    EMAError
        One line naming the pick (and ``picks.file``) when a pick has no pole of its order within
        ``freq_tol``, when two picks take the same pole, or when a pick gives no mode inside the band; or
        an error of :func:`ema.fit` (bad band, order).
    """
    if not isinstance(picks, Picks):
        raise TypeError(f"fit_with_picks: expected a Picks, got {type(picks).__name__}")
    if not freq_tol > 0:
        raise EMAError(f"freq_tol {freq_tol}: expected > 0")
    where = f"picks for {picks.file}"
    for order, f in picks.picks:
        if order > picks.max_order:  # refused before the poles are estimated
            raise EMAError(f"{where}: pick ({order}, {f:.6g} Hz): order {order} above max_order "
                           f"{picks.max_order}, no pole of that order in the diagram")
    try:
        result = fit(frf, picks.band_hz, FitSettings(method=picks.method, n_bands=picks.n_bands),
                     max_order=picks.max_order, picks=list(picks.picks))
    except EMAError as exc:
        raise EMAError(f"{where}: {' '.join(str(exc).split())}") from None
    d = result.diagram
    taken: dict[int, tuple[int, float]] = {}
    for order, f in picks.picks:
        cand = np.flatnonzero(d.order == order)
        name = f"pick ({order}, {f:.6g} Hz)"
        if cand.size == 0:
            raise EMAError(f"{where}: {name}: order {order} has no pole in the diagram "
                           f"({d.method}, {d.band_hz[0]:g}-{d.band_hz[1]:g} Hz)")
        k = int(cand[np.argmin(np.abs(d.frequencies_hz[cand] - f))])
        if abs(d.frequencies_hz[k] - f) > freq_tol * f:
            raise EMAError(f"{where}: {name}: no pole of order {order} within {freq_tol:.3g} of it "
                           f"(nearest {d.frequencies_hz[k]:.6g} Hz); were the picks made on this file?")
        if k in taken:
            o2, f2 = taken[k]
            raise EMAError(f"{where}: {name} and pick ({o2}, {f2:.6g} Hz) take the same pole")
        taken[k] = (order, f)
    if result.model.n_modes != len(picks.picks):
        raise EMAError(f"{where}: {len(picks.picks)} picks gave {result.model.n_modes} modes inside the band "
                       f"({d.band_hz[0]:g}-{d.band_hz[1]:g} Hz); a pick at a band edge?")
    if elsewhere is not None and _narrower(frf, picks.band_hz):
        return _with_picked_band(frf, fit(frf, **elsewhere), result, picks.band_hz)
    return result


def _narrower(frf: FRFSet, band: tuple[float, float] | None) -> bool:
    """Does ``band`` leave out some of the FRFs' finite lines above 0 Hz?"""
    if band is None:
        return False
    lines = frf.freq_hz[frf.valid_lines() & (frf.freq_hz > 0)]
    return bool(lines.size) and (lines[0] < band[0] or lines[-1] > band[1])


def _with_picked_band(frf: FRFSet, auto: EMAResult, picked: EMAResult, band: tuple[float, float]) -> EMAResult:
    """The automatic fit's modes outside ``band`` with the picked ones inside, in one LSFD model."""
    f = auto.model.frequencies_hz
    parts = (auto.model.take(np.flatnonzero((f < band[0]) | (f > band[1]))), picked.model)
    poles = np.concatenate([m.poles for m in parts])
    order = np.argsort(np.abs(poles), kind="stable")

    def joined(name: str) -> np.ndarray:
        return np.concatenate([np.full(m.n_modes, np.nan) if getattr(m, name) is None
                               else np.asarray(getattr(m, name), float) for m in parts])[order]

    model = modal_model(frf, poles[order], auto.model.band_hz, method=f"{auto.model.method}+picks")
    model = replace(model, shapes=np.concatenate([m.shapes for m in parts], axis=1)[:, order],
                    quality=joined("quality"), frequency_std_hz=joined("frequency_std_hz"),
                    damping_std=joined("damping_std"))
    dom = mode_dominance(frf, model, auto.diagram.criteria.mac_min)
    return replace(auto, model=model, quality=fit_quality(frf, model), dominance=dom)
