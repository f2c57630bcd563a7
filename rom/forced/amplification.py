"""The mistuning amplification factor per (family, EO) (package notes)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ROMError
from .families import family_band
from .model import BladeModes
from .sweep import ForcedResponse, forced_response

__all__ = ["AmplificationFactor", "amplification_factor", "amplification_factors", "tuned_references"]


@dataclass(frozen=True, eq=False)
class AmplificationFactor:
    """The mistuning amplification factor of one (family, EO).

    Attributes
    ----------
    eo : int
    family : int or None
        The family (1-based) when the band came from :func:`family_band`.
    af : float
        Largest mistuned blade peak over the tuned disk's peak.
    worst_blade : int
        The mistuned disk's blade with the largest peak (1-based).
    tuned_peak : float
        The tuned disk's peak (the largest over its blades, which are equal to round-off).
    tuned_peak_hz : float
    mistuned : ForcedResponse
    tuned : ForcedResponse
    """

    eo: int
    family: int | None
    af: float
    worst_blade: int
    tuned_peak: float
    tuned_peak_hz: float
    mistuned: ForcedResponse
    tuned: ForcedResponse


def amplification_factor(mistuned: BladeModes, tuned: BladeModes, eo: int, band_hz, *, family: int | None = None,
                         tuned_response: ForcedResponse | None = None, **sweep) -> AmplificationFactor:
    """AF of engine order ``eo`` over ``band_hz``: the mistuned disk's largest blade peak over the tuned disk's.

    Both disks get the same force, band and sweep rule (``sweep``: the keyword arguments of
    :func:`forced_response`); damping is each model's own, so give them the same (:func:`family_damping`).

    Parameters
    ----------
    mistuned, tuned : BladeModes
    eo : int
    band_hz : (float, float)
    family : int, optional
        A label kept in the result.
    tuned_response : ForcedResponse, optional
        The tuned disk's sweep of this EO and band, computed once for many mistuned models
        (:func:`tuned_references`); it must have the same EO, band, force and form.

    Raises
    ------
    ROMError
        If the two models have different numbers of blades, a ``tuned_response`` of another sweep, or as
        :func:`forced_response`.
    """
    if mistuned.n_blades != tuned.n_blades:
        raise ROMError(f"the mistuned model has {mistuned.n_blades} blades, the tuned one {tuned.n_blades}")
    mis = forced_response(mistuned, eo, band_hz, **sweep)
    tun = forced_response(tuned, eo, band_hz, **sweep) if tuned_response is None else tuned_response
    if (tun.eo, tun.band_hz, tun.amplitude_n, tun.form) != (mis.eo, mis.band_hz, mis.amplitude_n, mis.form):
        raise ROMError(f"the tuned response is of EO {tun.eo}, band {tun.band_hz} Hz, {tun.amplitude_n} N, {tun.form}; "
                       f"expected EO {mis.eo}, band {mis.band_hz} Hz, {mis.amplitude_n} N, {mis.form}")
    k = int(np.argmax(tun.peaks))
    return AmplificationFactor(mis.eo, family, mis.max_peak / tun.max_peak, mis.worst_blade, tun.max_peak,
                               float(tun.peak_hz[k]), mis, tun)


def tuned_references(tuned: BladeModes, families: Sequence[int] = (1, 2, 3), eos: Iterable[int] | None = None, *,
                     margin: float = 0.02, candidates=None, **sweep) -> dict[tuple[int, int], ForcedResponse]:
    """The tuned disk's sweep of every (family, EO): bands from :func:`family_band`, EOs 0..⌊N/2⌋ by default.

    Computed once, they serve every mistuned model (posterior samples) through :func:`amplification_factors`.

    Returns
    -------
    dict
        ``(family, eo)`` → ForcedResponse, family-major, EOs ascending.
    """
    eos = list(range(tuned.n_blades // 2 + 1)) if eos is None else list(eos)
    out = {}
    for fam in families:
        band = family_band(tuned, fam, margin=margin, candidates=candidates)
        out.update({(int(fam), int(eo)): forced_response(tuned, eo, band, **sweep) for eo in eos})
    return out


def amplification_factors(mistuned: BladeModes, tuned: BladeModes, families: Sequence[int] = (1, 2, 3),
                          eos: Iterable[int] | None = None, *, margin: float = 0.02, candidates=None,
                          references: Mapping[tuple[int, int], ForcedResponse] | None = None,
                          **sweep) -> list[AmplificationFactor]:
    """AF for every (family, EO) of :func:`tuned_references` (given as ``references``, or computed here).

    Parameters
    ----------
    mistuned, tuned : BladeModes
    families, eos, margin, candidates :
        As :func:`tuned_references`; ignored when ``references`` is given.
    references : mapping (family, eo) → ForcedResponse, optional
        The tuned disk's sweeps, from :func:`tuned_references` with the same ``sweep`` keywords.

    Returns
    -------
    list of AmplificationFactor
        In the order of the references (family-major, EOs ascending).
    """
    if references is None:
        references = tuned_references(tuned, families, eos, margin=margin, candidates=candidates, **sweep)
    return [amplification_factor(mistuned, tuned, eo, ref.band_hz, family=fam, tuned_response=ref, **sweep)
            for (fam, eo), ref in references.items()]
