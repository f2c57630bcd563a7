"""The model error a virtual campaign carries (issue 9, "Case C"): the ROM with the *true* patterns.

Paper §8 defines Case C as the identification ROM with the reference contact patterns, against the
measurement. On a virtual campaign the reference patterns are the truth (``truth/patterns.npz``), so Case C
is the model error alone: contact springs, FE-level blade variation, damping and noise against the ROM's
exact ties and eigenvalue-perturbation mistuning (Eq. 19) with the EMA-identified blade deltas (Eq. 37).

It reads the campaign through ``ema`` exactly as a user's pipeline would (automatic selection, no
frequencies given) and never looks at the truth's frequencies.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import ema
from ema.mac import common_dofs, mac
from rom import cache
from rom.academic import AcademicParams, build_bladed_disk
from rom.contact import ContactPattern
from rom.mistuning import rom_deltas
from rom.rom_assembly import solve_d1b, solve_full

from .rig import rom_modal_model

__all__ = ["ModelError", "case_c", "rom_deltas"]  # rom_deltas lives in rom.mistuning


@dataclass(frozen=True, eq=False)
class ModelError:
    """Case C figures of a campaign.

    Attributes
    ----------
    d1b_rel_err : ndarray, shape (n_joints, n_modes)
        (f_ROM − f_EMA) / f_EMA of each joint's first modes, MAC-paired (NaN where unpaired).
    d1b_mac : ndarray, shape (n_joints, n_modes)
    full_rel_err : ndarray, shape (n_pairs,)
        The same for the full assembly's EMA modes, MAC-paired with the ROM's.
    full_mac : ndarray, shape (n_pairs,)
    n_full_ema : int
        EMA modes of the full assembly (paired or not).
    """

    d1b_rel_err: np.ndarray
    d1b_mac: np.ndarray
    full_rel_err: np.ndarray
    full_mac: np.ndarray
    n_full_ema: int

    def summary(self) -> dict:
        return {
            "full": {"mean_abs_df_pct": float(100 * np.mean(np.abs(self.full_rel_err))),
                     "mean_mac": float(np.mean(self.full_mac)), "n_paired": int(self.full_mac.size),
                     "n_ema_modes": self.n_full_ema},
            "d1b": {"max_abs_df_pct": float(100 * np.nanmax(np.abs(self.d1b_rel_err))),
                    "mean_abs_df_pct": float(100 * np.nanmean(np.abs(self.d1b_rel_err))),
                    "mean_mac": float(np.nanmean(self.d1b_mac))},
        }


def _pair(measured: ema.ModalModel, model: ema.ModalModel, n_first: int | None = None, by: str = "mac"):
    """Pair the first ``n_first`` measured modes with the model's.

    ``by="mac"``: ``ema.pair_modes`` (MAC inside a 5 % window). ``by="frequency"``: Hungarian assignment on
    the relative frequency difference inside the same window, for tests whose few measured DOFs cannot tell
    the modes apart by shape (a disk–one-blade seen from 3 blade points and one point per sector: the blade
    tip dominates every shape, so most modes look alike).

    Returns
    -------
    measured_index, model_index : ndarray of int
    rel_err : ndarray
        (f_model − f_measured) / f_measured of each pair.
    mac : ndarray
    """
    k = measured.n_modes if n_first is None else min(n_first, measured.n_modes)
    measured = ema.ModalModel(measured.frequencies_hz[:k], measured.damping_ratio[:k], measured.shapes[:, :k],
                              measured.dofs)
    if by == "mac":
        pr = ema.pair_modes(measured, model, freq_window=0.05, mac_min=0.3)
        return pr.pairs[:, 0], pr.pairs[:, 1], pr.freq_error, pr.mac
    fa, fb = measured.frequencies_hz, model.frequencies_hz
    rows, cols = ema.pair_by_frequency(fa, fb, 0.05)
    rel = fb[cols] / fa[rows] - 1
    pa, pb, _ = common_dofs(measured, model)
    return rows, cols, rel, np.diag(mac(pa[:, rows], pb[:, cols])) if rows.size else np.zeros(0)


def _ema(root: Path, test: dict) -> ema.ModalModel:
    """Automatic EMA of one test of the manifest, with the lab's ``max_order`` where it gives one."""
    return ema.fit(ema.read_uff(root / test["file"]), max_order=int(test.get("max_order", 60))).model


def case_c(
    campaign: str | Path, *, cache_dir=None, n_d1b_modes: int = 10, progress: Callable[[str], None] | None = None
) -> ModelError:
    """Case C of a virtual campaign: the ROM with the true patterns and the EMA deltas vs the EMA modes."""
    say = progress or (lambda msg: None)
    root = Path(campaign)
    manifest = tomllib.loads((root / "campaign.toml").read_text(encoding="utf-8"))
    model = manifest["model"]
    params = AcademicParams.for_blades(int(model["n_blades"]), disk_scale=float(model.get("disk_scale", 1.0)),
                                       grid=tuple(model["grid"]), level=model["level"])
    with np.load(root / "truth" / "patterns.npz") as z:
        patterns = [ContactPattern(a, b) for a, b in zip(z["L"], z["R"], strict=True)]
    tests = manifest["tests"]

    say("EMA of the blades")
    blade_models = {f"blade_{t['blade']:02d}": _ema(root, t) for t in tests if t["type"] == "blade"}
    freqs = ema.campaign.frequency_table(blade_models).to_numpy()
    deltas = ema.blade_deltas(blade_models).to_numpy()

    say("reduced models (cached)")
    bd = build_bladed_disk(params)
    cb = cache.cached_reduce_disk(bd, (1,), cache_dir=cache_dir)
    blade = cache.cached_reduce_blade(bd, cache_dir=cache_dir)
    delta = rom_deltas(freqs, deltas, blade.frequencies_hz)

    d1b_err = np.full((params.n_blades, n_d1b_modes), np.nan)
    d1b_mac = np.full((params.n_blades, n_d1b_modes), np.nan)
    for t in (t for t in tests if t["type"] == "d1b"):
        s = int(t["joint"])
        say(f"disk-one-blade {s}")
        measured = _ema(root, t)
        rom_modes = solve_d1b(cb, blade, patterns[s - 1], s, n_modes=2 * n_d1b_modes + 6, delta=delta[s - 1])
        i, _, rel, mac = _pair(measured, rom_modal_model(rom_modes), n_d1b_modes, by="frequency")
        d1b_err[s - 1, i] = rel  # (f_ROM − f_EMA) / f_EMA
        d1b_mac[s - 1, i] = mac

    say("full assembly: EMA")
    full_test = next(t for t in tests if t["type"] == "assembly")
    measured = _ema(root, full_test)
    say("full assembly: ROM")
    # Enough ROM modes to cover the measured band (+5 %, the pairing window): invisible modes interleave.
    n_rom = measured.n_modes + params.n_blades
    while True:
        rom_modes = solve_full(bd, blade, {s + 1: p for s, p in enumerate(patterns)}, delta, n_modes=n_rom)
        if rom_modes.frequencies_hz[-1] >= 1.05 * measured.frequencies_hz.max() or n_rom > 4 * measured.n_modes:
            break
        n_rom += params.n_blades
    _, _, rel, mac = _pair(measured, rom_modal_model(rom_modes))
    return ModelError(d1b_err, d1b_mac, rel, mac, measured.n_modes)
