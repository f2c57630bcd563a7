"""The draft ``campaign.toml`` of ``bladetwin campaign init``: the guesses gathered, as TOML text with comments.

Every field a person must give holds a placeholder that ``bladetwin run`` refuses in one line (``grid = []``,
``family = "FILL IN"``, ``blade = 0`` …) under or beside a ``# FILL IN:`` comment saying what goes there; an
unsure guess carries a ``# GUESS:`` comment. The draft is written atomically. The guesses themselves are
:mod:`bladetwin.campaign_init`'s.
"""

from __future__ import annotations

import textwrap
import tomllib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import tomli_w

from .campaign_init import (
    TYPE_ORDER,
    UFF_SUFFIXES,
    FilmGuess,
    Numbering,
    TestGuess,
    find_inputs,
    guess_films,
    guess_tests,
    read_facts,
)
from .manifest_keys import CampaignError

__all__ = ["Draft", "draft_campaign", "FILL_IN", "render_draft", "check_target", "write_draft", "fill_in_count",
           "summary_lines"]

_WIDTH = 110  # characters of a comment line
#: The placeholder of a text or number field a person must fill in (refused by ``bladetwin run``).
FILL_IN = "FILL IN"

# The film fields a person gives from the scan (docs/campaign.md, "Film images"), with what goes there.
_FILM_FIELDS = (
    ("pixel_size", "m per pixel"),
    ("origin", "[row, col]: the pixel of grid node (0, 0)"),
    ("spacing", "[axial, radial] grid spacing, m"),
    ("contact_level", "gray level of the contact threshold (contact where gray < it)"),
)


@dataclass(frozen=True)
class Draft:
    """Everything the draft manifest says, guessed; ``n_blades`` None where no file tells it."""

    folder: Path
    name: str
    kind: str
    n_blades: int | None
    n_blades_note: str
    frf_units: str | None
    known_joints: tuple[int, ...]
    tests: tuple[TestGuess, ...]
    films: tuple[FilmGuess, ...]
    numbering: Numbering


def draft_campaign(folder: str | Path, numbering: Numbering | None = None) -> Draft:
    """Guess a campaign's manifest from the UFF files and images under ``folder``.

    Raises
    ------
    CampaignError
        Not a folder, no UFF file under it, or a file that no rule explains: one line naming it.
    ema.EMAError
        A UFF file that does not read (named by ``ema.read_uff``).
    """
    folder = Path(folder)
    num = numbering or Numbering()
    if not folder.is_dir():
        raise CampaignError(f"{folder}: not a folder (expected a folder of UFF files and film scans)")
    uffs, images = find_inputs(folder)
    if not uffs:
        raise CampaignError(f"{folder}: no UFF file under it (*{', *'.join(UFF_SUFFIXES)}): campaign init drafts "
                            "the manifest from the hammer tests' UFF files")
    facts = read_facts(folder, uffs)
    tests, n_blades, source = guess_tests(facts, num)
    films = guess_films(folder, images, n_blades)
    # the filmed joints are those with a film of each flank (the run needs both)
    known = tuple(sorted(j for j in {f.joint for f in films if f.joint is not None}
                         if {f.flank for f in films if f.joint == j} >= {"L", "R"}))
    units = {f.units for f in facts}
    kind = "virtual" if (folder / "truth" / "truth.json").is_file() else "lab"
    return Draft(folder, folder.resolve().name, kind, n_blades, source,
                 units.pop() if len(units) == 1 and "" not in units else None, known, tuple(tests), tuple(films), num)


def _value(v) -> str:
    """A TOML value: lists of numbers on one line, the rest as tomli_w writes it (quoting, escapes)."""
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return tomli_w.dumps({"v": v}).strip()[len("v = "):]


def _line(key: str, value, comment: str = "") -> str:
    text = f"{key} = {_value(value)}"
    return f"{text:<28} # {comment}" if comment else text


def _comments(*notes: str) -> list[str]:
    """Comment lines, each note wrapped to the draft's width (a lab reads it in any editor)."""
    return [f"# {line}" for n in notes for line in textwrap.wrap(n, _WIDTH - 2, break_on_hyphens=False)]


def _campaign_table(d: Draft) -> list[str]:
    lines = ["[campaign]", _line("name", d.name)]
    why = "truth/truth.json is here: made by `bladetwin lab simulate`" if d.kind == "virtual" else ""
    lines.append(_line("kind", d.kind, why))
    if d.n_blades is None:
        lines += [*_comments("FILL IN: the number of blades (slots); no d1b, assembly or disk test tells it"),
                  "n_blades = 0"]
    else:
        lines += [*_comments(f"n_blades from {d.n_blades_note}"), _line("n_blades", d.n_blades)]
    lines += [*_comments("FILL IN: the contact grid of a flank, [rows (axial), cols (radial)], e.g. [7, 31]"),
              "grid = []"]
    if len(d.known_joints) >= 2:
        lines += [*_comments("GUESS: the filmed joints, those with a film of each flank"),
                  _line("known_joints", list(d.known_joints))]
    else:
        lines += [*_comments("FILL IN: the filmed joints (1-based, at least 2, each with an L and an R film)"),
                  "known_joints = []"]
    if d.frf_units is not None:
        lines += [*_comments("the FRF unit label every UFF file carries (checked before any work)"),
                  _line("frf_units", d.frf_units)]
    else:
        lines += _comments("frf_units: the files carry no common unit label; give each test its units = \"…\"")
    if not d.numbering.is_default:
        n = d.numbering
        lines += _comments(f"node numbering (--numbering): point p of the blade in slot s is node {n.blade_offset} "
                           f"+ {n.stride} s + p, the disk point of sector s node {n.disk_offset} + s")
    return lines


def _model_table() -> list[str]:
    return ["[model]",
            *_comments("FILL IN: the FE model: \"academic\" (the embedded twin; add level = \"coarse\", "
                       "\"default\" or \"fine\") or \"imported\" (a lab's FE model, e.g. file = "
                       "\"fe/model.toml\"; docs/campaign.md, \"The model\")"),
            _line("family", FILL_IN), "",
            *_comments("[masses] (optional; calibrates ρ, docs/campaign.md): disk_kg = the disk's mass, blade_kg = "
                       "one mass per blade (kg); slot_hardware_kg = the bolts that hold one blade (kg), put in the "
                       "model")]


def _test_block(t: TestGuess) -> list[str]:
    lines = [*_comments(*t.notes), "[[tests]]",
             _line("type", t.type) if t.type else _line("type", FILL_IN, "FILL IN: blade or disk"),
             _line("file", t.file)]
    key = {"blade": "blade", "d1b": "joint"}.get(t.type or "")
    if key is not None:
        lines.append(_line(key, t.index or 0, "FILL IN" if not t.index else ""))
    if not t.check_numbering:
        lines.append(_line("check_numbering", False))
    return lines


def _film_block(f: FilmGuess, n_blades: int | None) -> list[str]:
    lines = [*_comments(*f.notes), "[[films]]"]
    lines.append(_line("joint", f.joint) if f.joint else
                 _line("joint", 0, f"FILL IN: the joint of this scan (1 … {n_blades or 'n_blades'})"))
    lines.append(_line("flank", f.flank) if f.flank else _line("flank", FILL_IN, "FILL IN: L or R"))
    lines.append(_line("file", f.file))
    lines += [_line(key, FILL_IN, f"FILL IN: {what}") for key, what in _FILM_FIELDS]
    return lines


def _header(d: Draft) -> list[str]:
    n_tests, n_films = len(d.tests), len(d.films)
    return _comments(f"Draft campaign manifest, written by `bladetwin campaign init` from the {n_tests} UFF "
                     f"file{'s' if n_tests != 1 else ''} and {n_films} image{'s' if n_films != 1 else ''} under "
                     "this folder (docs/campaign.md). Give every field marked FILL IN (`bladetwin run` refuses "
                     "each placeholder in one line) and check the lines marked GUESS. Each test's type and d1b "
                     "joint come from its DOF set and the numbering of docs/campaign.md.")


_BLADE_NOTE = ("The blade tests measure the same points on every blade: each blade number comes from the file "
               "name.")
_FILM_NOTE = ("Films (docs/campaign.md, \"Film images\"): give each FILL IN, or delete the line to read the film "
              "without it: without contact_level, Otsu's threshold; without pixel_size, origin and spacing (all "
              "three or none), the film placed on its imprint. Other metadata: white, grid, node_origin, "
              "threshold_pressure, p_sat.")


def render_draft(d: Draft) -> str:
    """The draft manifest's text (valid TOML: checked by parsing it back)."""
    lines = [*_header(d), "", *_campaign_table(d), "", *_model_table()]
    named = [t for t in d.tests if t.type == "blade" and t.index]
    for t in d.tests:
        lines += ["", *(_comments(_BLADE_NOTE) if named and t is named[0] else []), *_test_block(t)]
    if d.films:
        lines += ["", *_comments(_FILM_NOTE)]
    for f in d.films:
        lines += ["", *_film_block(f, d.n_blades)]
    text = "\n".join(lines) + "\n"
    tomllib.loads(text)  # a draft that is not TOML would fail the user's first run: fail here instead
    return text


def check_target(folder: Path, force: bool) -> Path:
    """``folder / campaign.toml``, if the draft may be written there; CampaignError naming it if not."""
    path = Path(folder) / "campaign.toml"
    if path.exists() and not force:
        raise CampaignError(f"{path}: exists; campaign init does not overwrite a manifest (--force replaces it)")
    return path


def write_draft(d: Draft, force: bool = False) -> Path:
    """Write ``d.folder / campaign.toml`` atomically; refuse to replace one unless ``force``.

    Raises
    ------
    CampaignError
        The manifest exists and ``force`` is False.
    """
    from rom.fileio import atomic_path

    path = check_target(d.folder, force)
    text = render_draft(d)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def _span(indices: list[int]) -> str:
    """1, 2, 3, 5 → "1–3, 5"."""
    out, run = [], []
    for k in sorted(set(indices)):
        if run and k != run[-1] + 1:
            out.append(f"{run[0]}–{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)))
            run = []
        run.append(k)
    if run:
        out.append(f"{run[0]}–{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)))
    return ", ".join(out)


def fill_in_count(d: Draft) -> int:
    """How many fields of the draft hold a placeholder (what ``bladetwin run`` will refuse until given)."""
    head = (d.n_blades is None) + 1 + (len(d.known_joints) < 2) + 1  # n_blades, grid, known_joints, [model]
    tests = sum((t.type is None) + (t.type in ("blade", "d1b") and not t.index) for t in d.tests)
    films = sum((f.joint is None) + (f.flank is None) + len(_FILM_FIELDS) for f in d.films)
    return head + tests + films


def summary_lines(d: Draft, path: Path) -> list[str]:
    """What was guessed: one line per test type with its count, the films, what is left to do, the draft."""
    counts = Counter(t.type or "unknown" for t in d.tests)
    lines = []
    for kind in (*TYPE_ORDER, "unknown"):
        if not counts[kind]:
            continue
        idx = [t.index for t in d.tests if t.type == kind and t.index]
        what = {"blade": "blades", "d1b": "joints"}.get(kind)
        lines.append(f"{kind:<9}{counts[kind]:>4}" + (f"  {what} {_span(idx)}" if what and idx else ""))
    joints = [f.joint for f in d.films if f.joint]
    lines.append(f"{'films':<9}{len(d.films):>4}" + (f"  joints {_span(joints)}" if joints else ""))
    fill = fill_in_count(d)
    notes = [n for e in (*d.tests, *d.films) for n in e.notes]
    guess = sum(n.startswith("GUESS") for n in notes) + (len(d.known_joints) >= 2)  # + the filmed joints
    lines.append(f"n_blades {d.n_blades or '?'}; {fill} field(s) to FILL IN, {guess} GUESS line(s) to check")
    lines.append(f"draft: {path}")
    return lines
