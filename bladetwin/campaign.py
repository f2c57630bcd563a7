"""Reading a campaign folder: ``campaign.toml`` and the files it names (docs/campaign.md).

Floor 3: this is file-system orchestration, shared by ``bladetwin identify`` and ``bladetwin run``. Every
problem with a manifest is one line naming the file, the field and what was expected.
"""

from __future__ import annotations

import contextvars
from dataclasses import dataclass, field
from pathlib import Path

from .manifest_keys import (
    CAMPAIGN_KEYS,
    FILM_KEYS,
    MASS_KEYS,
    TEST_KEYS,
    TOP_KEYS,
    CampaignError,
    check_keys,
    film_meta_message,
    mass_message,
    need_field,
    read_grid,
    read_toml,
)

__all__ = ["Campaign", "CampaignError", "FilmEntry", "TestEntry", "read_campaign", "model_family",
           "imported_model_table", "ACADEMIC_MODEL_KEYS", "IMPORTED_MODEL_KEYS"]

TEST_TYPES = ("blade", "disk", "d1b", "assembly")

#: Keys of a ``[model]`` table naming the academic twin.
ACADEMIC_MODEL_KEYS = ("family", "level", "n_blades", "grid", "disk_scale")
#: Keys of a ``[model]`` table describing an imported FE model (those of ``bladetwin fe export``'s
#: ``model.toml``, read by :func:`rom.importers.model.load_bladed_disk`), besides ``family`` and ``file``.
IMPORTED_MODEL_KEYS = ("format", "units", "disk", "blade", "placement", "grids")
# Keys of [model.disk] / [model.blade] that name files.
_COMPONENT_FILE_KEYS = ("K", "M", "file", "archive", "dofmap", "coords", "node_sets")


@dataclass(frozen=True)
class TestEntry:
    """One UFF file of the campaign.

    Attributes
    ----------
    type : {"blade", "disk", "d1b", "assembly"}
    file : Path
        Absolute path of the UFF file.
    index : int or None
        Blade (``blade`` tests) or joint (``d1b`` tests), 1-based; None for the disk and the assembly.
    max_order : int
        Highest model order of the pole estimator (the manifest's optional EMA hint; default 60).
    picks : Path or None
        A picks file (``ema.save_picks``): hand-picked poles that replace the automatic selection.
    units : str or None
        FRF unit label the manifest expects (``units`` of the test, else ``frf_units`` of ``[campaign]``),
        checked against the file's own label before any computation; None: the same label as the other files.
    check_numbering : bool
        Check the file's node numbers against its type and blade/joint (``campaign_checks.check_numbering``).
    """

    __test__ = False  # not a pytest class, despite the name

    type: str
    file: Path
    index: int | None
    max_order: int = 60
    picks: Path | None = None
    units: str | None = None
    check_numbering: bool = True


@dataclass(frozen=True)
class FilmEntry:
    """One film scan: joint (1-based), flank ("L"/"R"), absolute file path, and its metadata mapping."""

    joint: int
    flank: str
    file: Path
    meta: dict = field(default_factory=dict)

    @property
    def contact_level(self) -> float | None:
        """Gray level of the contact threshold, if the manifest gives one (contact where gray < level)."""
        v = self.meta.get("contact_level")
        return None if v is None else float(v)


@dataclass(frozen=True)
class Campaign:
    """A campaign's manifest, checked, with absolute file paths.

    Attributes
    ----------
    root : Path
    name, kind : str
        ``kind`` is "virtual" (made by ``bladetwin lab simulate``, has ``truth/``) or "lab".
    n_blades : int
    grid : (int, int)
        Contact grid per flank (rows, cols).
    known_joints : tuple of int
        The filmed joints (1-based).
    model : dict
        The ``[model]`` table: the academic twin's (family, level, n_blades, grid) or an imported model's
        (:func:`imported_model_table`; docs/campaign.md).
    tests : tuple of TestEntry
    films : tuple of FilmEntry
    masses : dict
        The optional ``[masses]`` table (kg): ``disk_kg`` (float) and ``blade_kg`` (one float for the mean
        blade, or one per blade), the components weighed for the calibration of ρ (paper §5); and
        ``slot_hardware_kg``, what holds each mounted blade (its bolts), which the model then carries.
    """

    root: Path
    name: str
    kind: str
    n_blades: int
    grid: tuple[int, int]
    known_joints: tuple[int, ...]
    model: dict
    tests: tuple[TestEntry, ...]
    films: tuple[FilmEntry, ...]
    masses: dict = field(default_factory=dict)

    def of_type(self, kind: str) -> list[TestEntry]:
        """The tests of one type, in blade/joint order."""
        return sorted((t for t in self.tests if t.type == kind), key=lambda t: t.index or 0)

    def film(self, joint: int, flank: str) -> FilmEntry:
        for f in self.films:
            if f.joint == joint and f.flank == flank:
                return f
        raise CampaignError(f"{self.root / 'campaign.toml'}: no film for joint {joint} flank {flank}")

    @property
    def truth_dir(self) -> Path | None:
        """``truth/`` of a virtual campaign, or None."""
        d = self.root / "truth"
        return d if d.is_dir() else None


#: Set by ``read_campaign(..., allow_outside=True)`` (``--allow-outside``) while it reads one manifest.
_ALLOW_OUTSIDE = contextvars.ContextVar("allow_outside", default=False)


def _file(root: Path, rel, where: str) -> Path:
    if not isinstance(rel, str) or not rel:
        raise CampaignError(f"{where}: file = {rel!r}, expected a path relative to the campaign folder")
    path = (root / rel).resolve()
    # A lab's campaign reads its own folder: `../x` or `/etc/...` is a mistake unless the user says otherwise.
    if not _ALLOW_OUTSIDE.get() and not path.is_relative_to(root.resolve()):
        raise CampaignError(f"{where}: file {rel!r} is outside the campaign folder {root} (--allow-outside "
                            "permits it)")
    if not path.is_file():
        raise CampaignError(f"{where}: file {rel!r} not found in {root}")
    return path


def model_family(model: dict, where: str) -> str:
    """``"academic"`` or ``"imported"``: the family of a campaign's ``[model]`` table.

    ``family`` says it; without it, a table with any key of an imported model (``file`` or one of
    :data:`IMPORTED_MODEL_KEYS`) is imported, any other the academic twin.

    Raises
    ------
    CampaignError
        An unknown family, or academic and imported keys mixed.
    """
    imported = sorted(set(model) & {"file", *IMPORTED_MODEL_KEYS})
    family = model.get("family", "imported" if imported else "academic")
    if family not in ("academic", "imported"):
        raise CampaignError(f"{where}: family = {family!r}, expected 'academic' (the twin) or 'imported' (a lab's "
                            "FE model, docs/campaign.md)")
    if family == "academic":
        unknown = sorted(set(model) - set(ACADEMIC_MODEL_KEYS))
        if unknown:
            raise CampaignError(f"{where}: unknown key(s) {unknown} for family 'academic'; allowed: "
                                f"{list(ACADEMIC_MODEL_KEYS)} (an imported model says family = 'imported')")
    else:
        twin = sorted(set(model) & (set(ACADEMIC_MODEL_KEYS) - {"family"}))
        if twin:
            raise CampaignError(f"{where}: key(s) {twin} belong to the academic twin, not to an imported model "
                                "(its slots and grid come from its files)")
    return family


def imported_model_table(model: dict, root: Path, where: str) -> tuple[dict, Path, str]:
    """The table to import for an imported ``[model]``, the folder its paths are relative to, and its name.

    ``[model]`` either holds the table itself (paths relative to the campaign folder ``root``) or names, with
    ``file``, a TOML file whose ``[model]`` table it is (e.g. ``bladetwin fe export``'s ``model.toml``; paths
    relative to that file's folder).

    Raises
    ------
    CampaignError
        ``file`` beside other keys, a missing or unreadable file, a file without a ``[model]`` table.
    """
    if "file" not in model:
        return {k: v for k, v in model.items() if k != "family"}, root, where
    rest = sorted(set(model) - {"family", "file"})
    if rest:
        raise CampaignError(f"{where}: [model] file = {model['file']!r} names the model; {rest} belong in that file")
    rel = model["file"]
    if not isinstance(rel, str) or not rel:
        raise CampaignError(f"{where}: [model] file = {rel!r}, expected a path relative to the campaign folder")
    path = (root / rel).resolve()
    if not path.is_file():
        raise CampaignError(f"{where}: [model] file = {rel!r}: {path} not found")
    doc = read_toml(path)
    table = doc.get("model")
    if not isinstance(table, dict):
        raise CampaignError(f"{path}: no [model] table (expected the model.toml of `bladetwin fe export`)")
    return table, path.parent, str(path)


def _check_imported_model(model: dict, root: Path, n_blades: int, grid: tuple[int, int], where: str) -> None:
    """What the manifest can tell of an imported model without reading its matrices: slots, grid, files.

    The full check (matrix sizes, node sets, grid conformity) needs the import itself, which
    :func:`bladetwin.model.load_model` does; this one makes a wrong count or a missing file fail in seconds.
    """
    table, base, where = imported_model_table(model, root, where)
    placement = table.get("placement")
    if isinstance(placement, dict) and "n_slots" in placement and placement["n_slots"] != n_blades:
        raise CampaignError(f"{where}: [model.placement] n_slots = {placement['n_slots']!r}, but the campaign has "
                            f"n_blades = {n_blades}")
    grids = table.get("grids")
    if isinstance(grids, dict) and "shape" in grids and list(grids["shape"]) != list(grid):
        raise CampaignError(f"{where}: [model.grids] shape = {grids['shape']!r}, but the campaign's grid is "
                            f"{list(grid)}")
    named = [("grids", "file", grids.get("file"))] if isinstance(grids, dict) else []
    for comp in ("disk", "blade"):
        t = table.get(comp)
        if isinstance(t, dict):
            named += [(comp, k, t[k]) for k in _COMPONENT_FILE_KEYS if k in t]
    for comp, key, rel in named:
        if not isinstance(rel, str) or not rel:
            raise CampaignError(f"{where}: [model.{comp}] {key} = {rel!r}, expected a file name")
        if not (base / rel).is_file():
            raise CampaignError(f"{where}: [model.{comp}] {key} = {rel!r}: {base / rel} not found")


def _check_model(model: dict, root: Path, n_blades: int, grid: tuple[int, int], path: Path) -> None:
    where = f"{path} [model]"
    if model_family(model, where) == "imported":
        # Its messages name the table themselves ([model.placement], ...), as rom.importers' do.
        _check_imported_model(model, root, n_blades, grid, str(path))
        return
    # The twin is built with the [model] values; a count or grid other than the campaign's would give an ROM
    # whose slots or contact nodes do not match the tests and films.
    for key, value in (("n_blades", n_blades), ("grid", list(grid))):
        if key in model and model[key] != value:
            raise CampaignError(f"{where}: {key} = {model[key]!r}, but [campaign] {key} = {value}")


def read_campaign(folder: str | Path, *, allow_outside: bool = False) -> Campaign:
    """Read and check ``folder/campaign.toml`` (docs/campaign.md).

    Raises
    ------
    CampaignError
        No folder or manifest, TOML syntax, a missing or mistyped field, an unknown test type, a blade or
        joint index out of range, a file that does not exist or (unless ``allow_outside``) lies outside the
        folder, a known joint without both films.
    """
    token = _ALLOW_OUTSIDE.set(bool(allow_outside))
    try:
        return _read_campaign(Path(folder))
    finally:
        _ALLOW_OUTSIDE.reset(token)


def _read_campaign(root: Path) -> Campaign:
    if not root.is_dir():
        raise CampaignError(f"{root}: not a campaign folder (expected a folder with campaign.toml)")
    path = root / "campaign.toml"
    if not path.is_file():
        raise CampaignError(f"{root}: no campaign.toml (docs/campaign.md describes the manifest)")
    doc = read_toml(path)
    check_keys(doc, TOP_KEYS, str(path))
    head = need_field(doc, "campaign", str(path), dict)
    where = f"{path} [campaign]"
    check_keys(head, CAMPAIGN_KEYS, where)
    n_blades = need_field(head, "n_blades", where, int)
    if n_blades < 2:
        raise CampaignError(f"{where}: n_blades = {n_blades}, expected ≥ 2")
    grid = read_grid(need_field(head, "grid", where, list), where)
    known = need_field(head, "known_joints", where, list)
    if not all(isinstance(k, int) and not isinstance(k, bool) and 1 <= k <= n_blades for k in known):
        raise CampaignError(f"{where}: known_joints = {known!r}, expected joints in 1..{n_blades}")
    if len(set(known)) != len(known):
        raise CampaignError(f"{where}: known_joints = {known!r} names a joint twice")
    if len(known) < 2:
        # The PCA sampler needs at least two films per flank to have a direction of variation (Eqs. 23-27).
        raise CampaignError(f"{where}: known_joints = {known!r}, expected at least 2 filmed joints (the PCA "
                            "sampler needs two films per flank)")
    default_units = head.get("frf_units")
    if default_units is not None and not isinstance(default_units, str):
        raise CampaignError(f"{where}: frf_units = {default_units!r}, expected a unit label such as 'm/s/N'")
    model = doc.get("model", {})
    if not isinstance(model, dict):
        raise CampaignError(f"{path}: [model] must be a table")
    _check_model(model, root, n_blades, grid, path)
    tests = _read_tests(doc, path, root, n_blades, default_units)
    films: dict[tuple[int, str], FilmEntry] = {}
    for k, f in enumerate(doc.get("films", [])):
        w = f"{path} films[{k}]"
        if not isinstance(f, dict):
            raise CampaignError(f"{w}: expected a table")
        check_keys(f, FILM_KEYS, w)
        joint = need_field(f, "joint", w, int)
        flank = need_field(f, "flank", w, str)
        if not 1 <= joint <= n_blades or flank not in ("L", "R"):
            raise CampaignError(f"{w}: joint {joint!r} flank {flank!r}, expected 1..{n_blades} and L or R")
        meta = {key: v for key, v in f.items() if key not in ("joint", "flank", "file")}
        if (msg := film_meta_message(meta, w)) is not None:
            raise CampaignError(msg)
        if (joint, flank) in films:
            raise CampaignError(f"{w}: joint {joint} flank {flank} is named twice")
        films[joint, flank] = FilmEntry(joint, flank, _file(root, f.get("file"), w), meta)
    missing = [(j, flank) for j in known for flank in ("L", "R") if (j, flank) not in films]
    if missing:
        raise CampaignError(f"{path}: known joint {missing[0][0]} has no film for flank {missing[0][1]}")
    unknown = [k for k, (j, _) in enumerate(films) if j not in known]
    if unknown:
        j = list(films)[unknown[0]][0]
        raise CampaignError(f"{path} films[{unknown[0]}]: joint {j} is not in known_joints {known}: add it there to "
                            "use its film, or remove the film")
    return Campaign(root.resolve(), str(head.get("name", root.name)), str(head.get("kind", "lab")), n_blades, grid,
                    tuple(int(k) for k in known), dict(model), tuple(tests), tuple(films.values()),
                    _read_masses(doc, path, n_blades))


def _read_masses(doc: dict, path: Path, n_blades: int) -> dict:
    """The checked ``[masses]`` table (kg), or ``{}``."""
    masses = doc.get("masses", {})
    where = f"{path} [masses]"
    if not isinstance(masses, dict):
        raise CampaignError(f"{where}: expected a table with disk_kg, blade_kg and/or slot_hardware_kg")
    check_keys(masses, MASS_KEYS, where)
    if (msg := mass_message(masses, where, n_blades)) is not None:
        raise CampaignError(msg)
    return dict(masses)


def _read_tests(doc: dict, path: Path, root: Path, n_blades: int, default_units: str | None) -> list[TestEntry]:
    """The checked ``tests`` of the manifest ``path``: one per blade, per joint, one disk and one assembly (a
    second one is a manifest mistake that would otherwise silently replace the first)."""
    tests: list[TestEntry] = []
    seen: dict[tuple, int] = {}
    for k, t in enumerate(need_field(doc, "tests", str(path), list)):
        w = f"{path} tests[{k}]"
        if not isinstance(t, dict):
            raise CampaignError(f"{w}: expected a table")
        check_keys(t, TEST_KEYS, w)
        kind = need_field(t, "type", w, str)
        if kind not in TEST_TYPES:
            raise CampaignError(f"{w}: type = {kind!r}, expected one of {', '.join(TEST_TYPES)}")
        key = {"blade": "blade", "d1b": "joint"}.get(kind)  # the field naming the test's blade or joint
        index = None if key is None else need_field(t, key, w, int)
        if key is not None and not 1 <= index <= n_blades:
            raise CampaignError(f"{w}: {key} = {index}, expected 1..{n_blades}")
        if (kind, index) in seen:
            what = f"the {kind}" if key is None else f"{key} {index}"
            raise CampaignError(f"{w}: {what} is named twice (also tests[{seen[kind, index]}])")
        seen[kind, index] = k
        order = t.get("max_order", 60)
        if not isinstance(order, int) or isinstance(order, bool) or order < 2:
            raise CampaignError(f"{w}: max_order = {order!r}, expected an integer ≥ 2")
        units = t.get("units", default_units)
        if units is not None and not isinstance(units, str):
            raise CampaignError(f"{w}: units = {units!r}, expected a unit label such as 'm/s/N'")
        check = t.get("check_numbering", True)
        if not isinstance(check, bool):
            raise CampaignError(f"{w}: check_numbering = {check!r}, expected true or false")
        tests.append(TestEntry(kind, _file(root, t.get("file"), w), index, order,
                               None if t.get("picks") is None else _file(root, t["picks"], f"{w} picks"), units, check))
    return tests
