"""The files of a campaign against its manifest, from what each file says itself (docs/campaign.md, "Checks").

Run before any long computation (``bladetwin run``, ``bladetwin identify``). A lab's usual mistakes (a file
under the wrong name or test type, one file copied under two names, units mixed across files, a film given to
the wrong joint) would otherwise give an answer with no warning; each is refused in one line naming the file
and the manifest field.
"""

from __future__ import annotations

import hashlib
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from ema.frf import unit_factor
from ema.numbering import BLADE_NODE_STRIDE

from .campaign import Campaign, CampaignError, TestEntry

__all__ = ["check_files", "check_numbering", "film_identity"]

_JOINT_IN_NAME = re.compile(r"joint[_\- ]?0*(\d+)", re.IGNORECASE)
_FLANK_IN_NAME = re.compile(r"[_\-]([LR])(?:[_\-.]|$)")
_OFF = "(set check_numbering = false on this test if the lab numbers its points otherwise)"


def film_identity(path: Path) -> tuple[int | None, str | None, str]:
    """(joint, flank, where from) a film image says it shows: its PNG text fields, else its file name."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            info = dict(getattr(im, "text", {}) or {})
    except (UnidentifiedImageError, OSError) as exc:
        raise CampaignError(f"{path}: not a readable image ({exc})") from None
    if "joint" in info:
        try:
            return int(info["joint"]), info.get("flank"), "its PNG text field 'joint'"
        except ValueError:
            raise CampaignError(f"{path}: PNG text field joint = {info['joint']!r}, expected an integer") from None
    m = _JOINT_IN_NAME.search(path.stem)
    f = _FLANK_IN_NAME.search(path.stem)
    return (int(m.group(1)) if m else None), (f.group(1) if f else None), "its file name"


def check_numbering(test: TestEntry, nodes: set[int], manifest: Path) -> None:
    """A test's type and blade/joint against the UFF nodes it measures (``ema.numbering``: blade point p of slot s
    is node ``BLADE_NODE_STRIDE·s + p``, a disk point of sector s is node s).

    A d1b file must measure the blade of its own slot and no other; a blade or disk file no blade in a slot.
    """
    slots = sorted({n // BLADE_NODE_STRIDE for n in nodes if n >= BLADE_NODE_STRIDE})
    where = f"{test.file}: {manifest.name} gives it as the {test.type} test"
    if test.type == "d1b":
        where += f" of joint {test.index}"
        if not slots:
            raise CampaignError(f"{where}, but it measures no blade in a slot (no node ≥ {BLADE_NODE_STRIDE}) {_OFF}")
        if slots != [test.index]:
            what = f"joint {slots[0]}" if len(slots) == 1 else f"joints {slots}"
            raise CampaignError(f"{where}, but its blade nodes ({min(n for n in nodes if n >= BLADE_NODE_STRIDE)}…) "
                                f"are those of {what} {_OFF}")
    elif test.type in ("blade", "disk") and slots:
        raise CampaignError(f"{where}, but it measures blades in slots {slots} (nodes ≥ {BLADE_NODE_STRIDE}): a d1b "
                            f"or assembly test? {_OFF}")


@dataclass(frozen=True)
class _FileFacts:
    """What the cross-file checks need of one UFF (not its FRF array, so 38 files are not held at once)."""

    outputs: frozenset
    units: str
    digest: str  # blake2b of the FRF values: equal only for the same data


def _facts(frf) -> _FileFacts:
    digest = hashlib.blake2b(frf.H.tobytes(), digest_size=16).hexdigest()
    return _FileFacts(frozenset(frf.outputs), frf.units or "", digest)


def _check_consistency(campaign: Campaign, facts: dict[Path, _FileFacts], manifest: Path) -> None:
    """Across files: every blade test measures the same DOFs, the disk test not those; no two files hold the same
    FRFs; without a manifest unit label, every file carries the same units (``ema.frf.unit_factor`` 1: equal
    labels, or two spellings of one unit)."""
    tests = {t.file: t for t in campaign.tests}
    blade_dofs = Counter(facts[t.file].outputs for t in campaign.of_type("blade"))
    if blade_dofs:
        common, n = blade_dofs.most_common(1)[0]
        for t in campaign.of_type("blade"):
            if facts[t.file].outputs != common and n > 1:
                raise CampaignError(f"{t.file}: measures {sorted(facts[t.file].outputs)[:4]}…, not the DOFs of the "
                                    f"other blade tests ({sorted(common)[:4]}…): is it a blade test ({manifest.name} "
                                    f"tests, blade {t.index})?")
        for t in campaign.of_type("disk"):
            if facts[t.file].outputs == common:
                raise CampaignError(f"{t.file}: measures exactly the blade tests' DOFs: is it a blade test "
                                    f"({manifest.name} gives it as the disk test)?")
    seen: dict[str, Path] = {}
    for path, fact in facts.items():
        if fact.digest in seen:
            first = seen[fact.digest]
            raise CampaignError(f"{path}: the same FRFs as {first.name} ({manifest.name} tests: {tests[first].type} "
                                f"and {tests[path].type}); one file copied under two names?")
        seen[fact.digest] = path
    free = {p: fact.units for p, fact in facts.items() if tests[p].units is None}
    if free:
        usual = Counter(free.values()).most_common(1)[0][0]
        odd = next((p for p, units in free.items() if unit_factor(units, usual) != 1.0), None)
        if odd is not None:
            raise CampaignError(f"{odd}: FRF units {free[odd]!r}, but the other files carry {usual!r}: convert "
                                f"the file, or give each test's units in {manifest.name} (units / frf_units)")


def check_files(campaign: Campaign, say=lambda msg: None) -> None:
    """Check every file the manifest names before any long computation.

    Every UFF must read (``ema.read_uff`` refuses damaged files), carry the FRF unit label the manifest expects
    (``units`` / ``frf_units``, else the same label as the other files), measure the nodes its test type and
    blade/joint imply (:func:`check_numbering`, unless the test sets ``check_numbering = false``), and differ
    from every other file; a picks file must load. Every film must be a readable image whose joint and flank,
    where the image says (PNG text fields ``joint``/``flank``) or its file name does (``joint_07_L.png``), are
    the ones the manifest gives it.

    Raises
    ------
    CampaignError, ema.EMAError
        One line naming the file and what is wrong.
    """
    import ema

    manifest = campaign.root / "campaign.toml"
    facts = {}
    for t in campaign.tests:
        say(f"checking {t.file.name}")
        frf = ema.read_uff(t.file)
        facts[t.file] = _facts(frf)
        if t.units is not None and (frf.units or "").replace(" ", "") != t.units.replace(" ", ""):
            raise CampaignError(f"{t.file}: FRF units {frf.units!r}, but {manifest.name} says {t.units!r} "
                                "(units / frf_units): convert the file or correct the manifest")
        if t.check_numbering:
            check_numbering(t, {int(n) for n, _ in frf.outputs}, manifest)
        if t.picks is not None:
            ema.load_picks(t.picks)
    _check_consistency(campaign, facts, manifest)
    for f in campaign.films:
        joint, flank, source = film_identity(f.file)
        for what, said, given in (("joint", joint, f.joint), ("flank", flank, f.flank)):
            if said is not None and said != given:
                raise CampaignError(f"{manifest} films: {f.file.name} is a film of {what} {said} ({source}), but the "
                                    f"manifest gives it to {what} {given}")
