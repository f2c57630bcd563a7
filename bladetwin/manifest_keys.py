"""The keys a campaign manifest may hold, table by table, and the readers of its fields (one-line errors).

A typo'd optional key (``frf_unit``, ``max_ordr``) would otherwise be ignored and its default used in silence,
so every table of ``campaign.toml`` is checked against its list here (docs/campaign.md); an unknown key is refused
with the nearest allowed one.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from pathlib import Path

__all__ = ["CampaignError", "check_keys", "need_field", "read_toml", "read_grid",
           "TOP_KEYS", "CAMPAIGN_KEYS", "MASS_KEYS", "TEST_KEYS", "FILM_KEYS", "unknown_key_message",
           "film_meta_message", "mass_message"]

#: The manifest's top-level tables.
TOP_KEYS = ("campaign", "model", "tests", "films", "masses")
#: ``[campaign]``: identity, layout, the filmed joints, the FRF unit label; what wrote it and how films map.
CAMPAIGN_KEYS = ("name", "kind", "n_blades", "grid", "known_joints", "frf_units", "generated_by", "orientation",
                 "description")
#: ``[masses]``: the weighed components (kg), for the calibration of ρ.
MASS_KEYS = ("disk_kg", "blade_kg", "slot_hardware_kg")
#: ``[[tests]]``: one UFF file each.
TEST_KEYS = ("type", "file", "blade", "joint", "max_order", "picks", "units", "check_numbering")
#: ``[[films]]``: one scan each, with its film metadata (``identify.film.FilmGeometry``, ``lab.films.FilmMeta``
#: without the truth's own ``shift`` and ``rotation``).
FILM_KEYS = ("joint", "flank", "file", "grid", "spacing", "pixel_size", "origin", "node_origin", "contact_level",
             "white", "threshold_pressure", "p_sat", "orientation")


def unknown_key_message(table: dict, allowed: tuple[str, ...], where: str) -> str | None:
    """One line naming the first key of ``table`` not in ``allowed`` (and the nearest allowed one), or None."""
    unknown = [k for k in table if k not in allowed]
    if not unknown:
        return None
    key = unknown[0]
    near = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
    hint = f"; did you mean {near[0]!r}?" if near else ""
    return f"{where}: unknown key {key!r}{hint} (allowed: {', '.join(allowed)})"


_FILM_NUMBERS = ("pixel_size", "contact_level", "white", "threshold_pressure", "p_sat")
_FILM_PAIRS = ("grid", "spacing", "origin", "node_origin")
_FILM_GEOMETRY = ("origin", "spacing", "pixel_size")  # identify.film.FilmGeometry needs all three


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def film_meta_message(meta: dict, where: str) -> str | None:
    """One line naming the first unusable film metadata field (type, range, a geometry half given), or None."""
    for key in _FILM_NUMBERS:
        positive = key not in ("contact_level", "white")  # gray levels may be 0; sizes and pressures may not
        if key in meta and not (_number(meta[key]) and (meta[key] > 0 if positive else meta[key] >= 0)):
            return f"{where}: {key} = {meta[key]!r}, expected a {'positive' if positive else 'non-negative'} number"
    for key in _FILM_PAIRS:
        if key in meta and not (isinstance(meta[key], list) and len(meta[key]) == 2 and all(map(_number, meta[key]))):
            return f"{where}: {key} = {meta[key]!r}, expected two numbers [row, col]"
    geometry = [k for k in _FILM_GEOMETRY if k in meta]
    if geometry and len(geometry) < len(_FILM_GEOMETRY):
        missing = [k for k in _FILM_GEOMETRY if k not in meta]
        return f"{where}: film geometry gives {', '.join(geometry)} but lacks {', '.join(missing)} (all three or none)"
    if _number(meta.get("contact_level")) and _number(meta.get("white")) and meta["contact_level"] >= meta["white"]:
        return (f"{where}: contact_level = {meta['contact_level']} is not below white = {meta['white']}: every pixel "
                "would read as contact")
    return None


def _positive(v) -> bool:
    return _number(v) and math.isfinite(v) and v > 0


def mass_message(masses: dict, where: str, n_blades: int) -> str | None:
    """One line naming an unusable ``[masses]`` field, or None: ``disk_kg`` a positive number, ``blade_kg`` one
    positive number (the mean blade) or one per blade."""
    if "disk_kg" in masses and not _positive(masses["disk_kg"]):
        return f"{where}: disk_kg = {masses['disk_kg']!r}, expected the disk's mass in kg (> 0)"
    blade = masses.get("blade_kg")
    if blade is not None and not (_positive(blade) or (isinstance(blade, list) and len(blade) == n_blades
                                                      and all(map(_positive, blade)))):
        return (f"{where}: blade_kg = {blade!r}, expected the mean blade mass in kg (> 0) or one mass per blade "
                f"({n_blades})")
    hw = masses.get("slot_hardware_kg")
    if hw is not None and not (_number(hw) and math.isfinite(hw) and hw >= 0):
        return (f"{where}: slot_hardware_kg = {hw!r}, expected the mass in kg (≥ 0) of the hardware that holds each "
                "blade on the disk (its bolts)")
    return None


class CampaignError(ValueError):
    """A campaign folder or manifest that cannot be used, with a one-line message for the user."""


def check_keys(table: dict, allowed: tuple[str, ...], where: str) -> None:
    """CampaignError naming an unknown key of ``table`` and the nearest allowed one."""
    if (msg := unknown_key_message(table, allowed, where)) is not None:
        raise CampaignError(msg)


def need_field(table: dict, key: str, where: str, kind: type | tuple[type, ...]):
    """``table[key]``, of type ``kind`` (a bool is never a number); CampaignError naming ``where`` if not."""
    if key not in table:
        raise CampaignError(f"{where}: missing field {key!r}")
    value = table[key]
    if not isinstance(value, kind) or isinstance(value, bool):
        raise CampaignError(f"{where}: field {key!r} = {value!r} has the wrong type")
    return value


def read_toml(path: Path) -> dict:
    """The TOML document at ``path``; CampaignError in one line (file and parser message) if it is not TOML."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CampaignError(f"{path}: not valid TOML ({' '.join(str(exc).split())})") from None


def read_grid(value, where: str) -> tuple[int, int]:
    """A ``[rows, cols]`` grid of integers ≥ 2; CampaignError naming ``where`` if not."""
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 2 for v in value)):
        raise CampaignError(f"{where}: grid = {value!r}, expected [rows, cols] with integers ≥ 2")
    return int(value[0]), int(value[1])
