"""``bladetwin campaign init``: guess a campaign's tests from the DOF sets of its UFF files (docs/campaign.md).

Every UFF file already says what it measures: its response and reference ``(node, direction)`` labels. With the
campaign's numbering (``ema.numbering``: point p of the blade in slot s is node ``1000 s + p``, the disk point
of sector s is node ``s``, point p of a blade tested alone is node ``p``) that set implies the test type and
the blade or joint:

* blade nodes of exactly one slot: the ``d1b`` test of that joint;
* blade nodes of two slots or more: the ``assembly`` test;
* no blade node in a slot, and only the points of a blade (those the slot tests measure on their blades): a
  ``blade`` test, whose blade the DOFs cannot tell (every blade test measures the same points), so the file
  name gives it;
* no blade node in a slot, and one point per sector (nodes 1 … n_blades, one direction): the ``disk`` test.

A file that fits no rule is refused in one line naming it; a file that fits two is settled by its name where
the name says which, and the draft says so. The draft is assembled and written by :mod:`bladetwin.campaign_draft`.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

from ema.numbering import BLADE_NODE_STRIDE

# film_identity: the reading of a film's joint and flank that `bladetwin run` checks the manifest against; the
# draft guesses with the same one, so it never writes what the run then refuses.
from .campaign_checks import check_numbering, film_identity
from .manifest_keys import CampaignError, unknown_key_message

__all__ = ["Numbering", "parse_numbering", "UffFacts", "TestGuess", "FilmGuess", "find_inputs", "read_facts",
           "guess_tests", "guess_films", "UFF_SUFFIXES", "IMAGE_SUFFIXES", "TYPE_ORDER"]

#: File name endings read as UFF files and as film images (case-insensitive).
UFF_SUFFIXES = (".uff", ".unv")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
#: Test types in the draft's order (that of docs/campaign.md).
TYPE_ORDER = ("blade", "disk", "d1b", "assembly")
_NUMBERING_KEYS = ("stride", "blade_offset", "disk_offset")
_BLADE_IN_NAME = re.compile(r"blade[_\- ]?0*(\d+)", re.IGNORECASE)
_LAST_NUMBER = re.compile(r"(\d+)\D*$")
_FLANK_WORD = re.compile(r"(?:^|[_\-. ])(left|right)(?:$|[_\-. ])", re.IGNORECASE)

DOF = tuple[int, int]


@dataclass(frozen=True)
class Numbering:
    """How a lab numbers its UFF nodes (docs/campaign.md, "campaign init"): the default is ``ema.numbering``'s.

    Point p of the blade in slot s is node ``blade_offset + stride · s + p``; the disk point of sector s is
    node ``disk_offset + s``; point p of a blade tested alone is node ``p``. A node at or above
    ``blade_offset + stride`` is a blade node in a slot, any other a disk point or a free blade's point.
    """

    stride: int = BLADE_NODE_STRIDE
    blade_offset: int = 0
    disk_offset: int = 0

    @property
    def is_default(self) -> bool:
        return self == Numbering()

    def slot_point(self, node: int) -> tuple[int, int] | None:
        """(slot, point) of a blade node in a slot, None for a disk point or a free blade's point."""
        k = node - self.blade_offset
        return (k // self.stride, k % self.stride) if k >= self.stride else None

    def sector(self, node: int) -> int:
        return node - self.disk_offset


def parse_numbering(text: str | None) -> Numbering:
    """``--numbering stride=100,blade_offset=0,disk_offset=100`` as a :class:`Numbering` (None: the default).

    Raises
    ------
    CampaignError
        One line naming the item and what was expected.
    """
    if not text:
        return Numbering()
    where = f"--numbering {text!r}"
    values: dict[str, int] = {}
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        key, sep, value = (s.strip() for s in item.partition("="))
        if not sep:
            raise CampaignError(f"{where}: {item!r} is not KEY=VALUE (keys: {', '.join(_NUMBERING_KEYS)})")
        if (msg := unknown_key_message({key: 0}, _NUMBERING_KEYS, where)) is not None:
            raise CampaignError(msg)
        low = 2 if key == "stride" else 0  # a stride of 1 leaves no room for a blade's points
        if not re.fullmatch(r"\d+", value) or int(value) < low:
            raise CampaignError(f"{where}: {key} = {value!r}, expected an integer ≥ {low}")
        values[key] = int(value)
    return Numbering(**values)


@dataclass(frozen=True)
class UffFacts:
    """What the guess needs of one UFF file: its path relative to the campaign folder, DOFs and unit label."""

    rel: str
    outputs: tuple[DOF, ...]
    inputs: tuple[DOF, ...]
    units: str


@dataclass(frozen=True)
class TestGuess:
    """One ``[[tests]]`` entry of the draft.

    ``type`` is None where the DOFs fit two rules and the name decides neither (to fill in); ``index`` the
    blade (blade tests) or joint (d1b tests), None for the disk and the assembly, 0 where it is to be filled
    in. ``notes`` are the draft's comments on the entry; ``check_numbering`` is False where the file's nodes
    do not follow the default numbering (a lab's own, given by ``--numbering``).
    """

    __test__ = False  # not a pytest class, despite the name

    file: str
    type: str | None
    index: int | None
    notes: tuple[str, ...] = ()
    check_numbering: bool = True


@dataclass(frozen=True)
class FilmGuess:
    """One ``[[films]]`` entry: joint (None: to fill in), flank (None: to fill in), and the draft's comments."""

    file: str
    joint: int | None
    flank: str | None
    notes: tuple[str, ...] = ()


def find_inputs(folder: Path) -> tuple[list[Path], list[Path]]:
    """The UFF files and the images under ``folder``, recursively, sorted; hidden files and a virtual campaign's
    ``truth/`` (what the identification never sees, with its own film of every joint) left out."""
    truth = folder / "truth"
    skip_truth = (truth / "truth.json").is_file()
    uffs, images = [], []
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        rel = path.relative_to(folder)
        if any(part.startswith(".") for part in rel.parts) or (skip_truth and rel.parts[0] == "truth"):
            continue
        suffix = path.suffix.lower()
        if suffix in UFF_SUFFIXES:
            uffs.append(path)
        elif suffix in IMAGE_SUFFIXES:
            images.append(path)
    return uffs, images


def read_facts(folder: Path, paths: list[Path]) -> list[UffFacts]:
    """The DOF sets of the UFF files (``ema.read_uff``: a damaged file is refused in one line naming it)."""
    import ema

    facts = []
    for path in paths:
        frf = ema.read_uff(path)
        facts.append(UffFacts(path.relative_to(folder).as_posix(), tuple(frf.outputs), tuple(frf.inputs),
                              frf.units or ""))
    return facts


def _dofs(dofs) -> str:
    """A DOF set for a message: the first three labels and a count."""
    dofs = sorted(dofs)
    more = f" … ({len(dofs)} DOFs)" if len(dofs) > 3 else ""
    return ", ".join(str(d) for d in dofs[:3]) + more


def _slot_test(f: UffFacts, num: Numbering) -> TestGuess | None:
    """The d1b or assembly test of a file with blade nodes in slots; None for a file without."""
    out_slots = {sp[0] for n, _ in f.outputs if (sp := num.slot_point(n))}
    in_slots = {sp[0] for n, _ in f.inputs if (sp := num.slot_point(n))}
    stray = sorted(in_slots - out_slots)
    if stray:
        # the hammer cannot hit a blade the laser does not see in the same test (it would not be mounted)
        raise CampaignError(f"{f.rel}: hammered at a blade in slot {stray[0]} (reference {_dofs(f.inputs)}) but "
                            f"measures {'no blade in a slot' if not out_slots else f'slots {sorted(out_slots)}'}: no "
                            "rule of docs/campaign.md explains it (--numbering if the lab numbers otherwise)")
    if not out_slots:
        return None
    has_disk = any(num.slot_point(n) is None for n, _ in f.outputs)
    if len(out_slots) == 1:
        (slot,) = out_slots
        notes = () if has_disk else (f"GUESS: blade nodes of slot {slot} only, no disk point: a d1b test?",)
        return TestGuess(f.rel, "d1b", slot, notes)
    return TestGuess(f.rel, "assembly", None)


@dataclass(frozen=True)
class _Reference:
    """What the slot tests say of the others: the blade points, the disk points, and the sector count."""

    blade_points: frozenset
    disk_points: frozenset
    n_blades: int | None


def _reference(slot_files: list[UffFacts], num: Numbering) -> _Reference:
    blade, disk = set(), set()
    for f in slot_files:
        for n, d in f.outputs:
            sp = num.slot_point(n)
            # a blade tested alone numbers its point p as node p, the same point in slot s as node 1000 s + p
            if sp:
                blade.add((sp[1], d))
            else:
                disk.add((n, d))
    slots = {sp[0] for f in slot_files for n, _ in f.outputs if (sp := num.slot_point(n))}
    sectors = {num.sector(n) for n, _ in disk}
    n = max(slots | sectors) if slots or sectors else None
    return _Reference(frozenset(blade), frozenset(disk), n)


def _is_ring(outputs, n: int | None, num: Numbering, directions: set[int]) -> bool:
    """One point per sector, sectors 1 … n, in the disk points' direction (when the slot tests show it)."""
    sectors = [num.sector(node) for node, _ in outputs]
    n = len(sectors) if n is None else n
    return (n >= 2 and sorted(sectors) == list(range(1, n + 1))
            and (not directions or {d for _, d in outputs} <= directions))


def _free_test(f: UffFacts, ref: _Reference, blade_set: frozenset | None, num: Numbering) -> TestGuess:
    """The blade or disk test of a file without blade nodes in slots, from its DOFs, or its name in a tie."""
    out = frozenset(f.outputs)
    have_slots = bool(ref.blade_points or ref.disk_points)
    if have_slots:
        is_blade = out <= ref.blade_points
        is_disk = _is_ring(out, ref.n_blades, num, {d for _, d in ref.disk_points})
    else:
        # No slot test to compare with: the blade tests are the files that measure the same DOFs, the disk the
        # one with a point per sector. A lone file of points 1 … n could be either (a free blade's points are
        # nodes 1, 2, 3): a tie, for the name to settle.
        ring = _is_ring(out, None, num, set())
        is_blade = out == blade_set if blade_set is not None else ring
        is_disk = out != blade_set and ring
    why = () if have_slots else ("GUESS: no d1b or assembly test to compare its DOFs with",)
    if is_blade != is_disk:
        return TestGuess(f.rel, "blade" if is_blade else "disk", 0 if is_blade else None, why)
    if not is_blade:
        expect = (f"the blade points of the slot tests ({_dofs(ref.blade_points)}) nor one disk point per sector "
                  f"(1 … {ref.n_blades})" if have_slots else "the DOFs of other blade tests nor one point per sector")
        raise CampaignError(f"{f.rel}: measures {_dofs(out)}, neither {expect}: no rule of docs/campaign.md "
                            "explains it (--numbering if the lab numbers its nodes otherwise)")
    stem = Path(f.rel).stem.lower()
    said = [k for k in ("blade", "disk") if k in stem]
    if len(said) == 1:
        note = f"its DOFs fit both the blade and the disk rules: the file name says {said[0]}"
        return TestGuess(f.rel, said[0], 0 if said[0] == "blade" else None, (*why, note))
    return TestGuess(f.rel, None, None, (*why, "FILL IN: its DOFs fit both the blade and the disk rules, and its "
                                         "name says neither: type = \"blade\" (with blade = N) or \"disk\""))


def _number_blades(tests: list[TestGuess], n_blades: int | None) -> list[TestGuess]:
    """Blade numbers from the file names (a blade test's DOFs are those of every blade); 0 where none fits."""
    found: dict[str, int | None] = {}
    for t in tests:
        if t.type == "blade":
            stem = Path(t.file).stem
            m = _BLADE_IN_NAME.search(stem) or _LAST_NUMBER.search(stem)
            k = int(m.group(1)) if m else None
            found[t.file] = k if k is not None and k >= 1 and (n_blades is None or k <= n_blades) else None
    counts = Counter(k for k in found.values() if k is not None)
    out = []
    for t in tests:
        if t.file not in found:
            out.append(t)
            continue
        k = found[t.file]
        if k is None:
            note = f"FILL IN: blade = N (the file name gives no blade number in 1 … {n_blades or 'n_blades'})"
            out.append(replace(t, index=0, notes=(*t.notes, note)))
        elif counts[k] > 1:
            others = [f for f, j in found.items() if j == k and f != t.file]
            out.append(replace(t, index=k, notes=(*t.notes, f"GUESS: {others[0]} also names blade {k}: keep one")))
        else:
            out.append(replace(t, index=k))
    return out


def _numbering_flag(t: TestGuess, f: UffFacts) -> TestGuess:
    """``check_numbering = false`` where the default rule (the one ``bladetwin run`` checks) refuses the file."""
    from .campaign import TestEntry

    if t.type is None:
        return t
    try:
        check_numbering(TestEntry(t.type, Path(t.file), t.index), {n for n, _ in f.outputs}, Path("campaign.toml"))
    except CampaignError:
        note = "its nodes follow the lab's numbering (--numbering), not docs/campaign.md's"
        return replace(t, notes=(*t.notes, note), check_numbering=False)
    return t


def guess_tests(facts: list[UffFacts], num: Numbering) -> tuple[list[TestGuess], int | None, str]:
    """Every file's test, the blade count and where the count comes from.

    Raises
    ------
    CampaignError
        A file that no rule explains, named.
    """
    slot = {f.rel: g for f in facts if (g := _slot_test(f, num)) is not None}
    ref = _reference([f for f in facts if f.rel in slot], num)
    free = [f for f in facts if f.rel not in slot]
    common = Counter(frozenset(f.outputs) for f in free).most_common(1)
    blade_set = common[0][0] if common and common[0][1] >= 2 else None
    guesses = {**slot, **{f.rel: _free_test(f, ref, blade_set, num) for f in free}}
    n_blades, source = ref.n_blades, "the d1b and assembly tests' slots and disk points"
    disks = [f for f in free if guesses[f.rel].type == "disk"]
    if n_blades is None and disks:
        n_blades, source = len(disks[0].outputs), f"the disk points of {disks[0].rel} (one per sector)"
    tests = _number_blades([guesses[f.rel] for f in facts], n_blades)
    by_file = {f.rel: f for f in facts}
    tests = [_numbering_flag(t, by_file[t.file]) for t in tests]
    tests = _mark_twins(tests)
    tests.sort(key=lambda t: (TYPE_ORDER.index(t.type) if t.type else len(TYPE_ORDER), t.index or 0, t.file))
    return tests, n_blades, source


def _mark_twins(tests: list[TestGuess]) -> list[TestGuess]:
    """A note on every test whose type and joint another file has too (a repeat: ``bladetwin run`` takes one)."""
    key = Counter((t.type, t.index) for t in tests if t.type in ("disk", "d1b", "assembly"))
    out = []
    for t in tests:
        if key.get((t.type, t.index), 0) > 1:
            what = f"the d1b test of joint {t.index}" if t.type == "d1b" else f"the {t.type} test"
            t = replace(t, notes=(*t.notes, f"GUESS: another file is {what} too: keep one"))
        out.append(t)
    return out


def _film_guess(folder: Path, path: Path, n_blades: int | None) -> FilmGuess:
    """Joint and flank of one image: its PNG text fields or the name ``bladetwin run`` checks it by, else any
    number and a left/right word in its name (unsure)."""
    rel = path.relative_to(folder).as_posix()
    try:
        joint, flank, source = film_identity(path)
    except CampaignError:
        return FilmGuess(rel, None, None, ("GUESS: not a readable image: is it a film scan?",))
    notes = []
    flank = flank if flank in ("L", "R") else None
    if joint is None and (m := _LAST_NUMBER.search(path.stem)):
        joint = int(m.group(1))
        notes.append(f"GUESS: joint {joint} from the last number of the file name")
    if flank is None and (w := _FLANK_WORD.search(path.stem)):
        flank = w.group(1)[0].upper()
        notes.append(f"GUESS: flank {flank} from the word {w.group(1)!r} in the file name")
    if joint is not None and n_blades is not None and not 1 <= joint <= n_blades:
        notes.append(f"GUESS: joint {joint} is not in 1 … {n_blades}")
        joint = None
    if joint is not None and flank is not None and not notes:
        notes.append(f"joint and flank from {source}")
    return FilmGuess(rel, joint, flank, tuple(notes))


def guess_films(folder: Path, images: list[Path], n_blades: int | None) -> list[FilmGuess]:
    """One entry per image, sorted by joint and flank (unknown ones last)."""
    films = [_film_guess(folder, p, n_blades) for p in images]
    return sorted(films, key=lambda f: (f.joint is None, f.joint or 0, f.flank or "~", f.file))
