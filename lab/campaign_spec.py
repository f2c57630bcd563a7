"""A campaign's specification and its truth twin, drawn from the seed (``lab.campaign`` writes the campaign).

Apart from :mod:`lab.campaign` so that :mod:`lab.truth_response` can rebuild an existing campaign's twin without
the writer (which writes the response truth with every campaign).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rom.academic import AcademicParams, build_bladed_disk, disk_scale_for
from rom.contact import ContactPattern

from .films import FilmParams
from .patterns import PressureParams, TruePressure, flank_coordinates, redraw_joints, simulate_pressure
from .truth import TruthParams, TruthTwin, make_truth_twin

__all__ = ["BLADE_MODES", "DISK_MODES", "D1B_MODES", "FULL_FAMILIES", "MAX_LINES", "TEST_TYPES", "CampaignSpec",
           "CampaignTwin", "assembly_solve_modes", "solved_modes", "campaign_twin", "default_known_joints"]

#: Modes each test must cover (issue 9 item 4): free blade, free disk, disk–one-blade; the full assembly
#: covers the first three blade-mode families (3 × n_blades modes) and the disk modes among them.
BLADE_MODES, DISK_MODES, D1B_MODES, FULL_FAMILIES = 8, 7, 10, 3
#: Spectral lines per test: the bundled campaign must stay small (≤ 40 MB; 8 bytes a complex value in
#: single-precision UFF 58b).
MAX_LINES = {"blade": 4000, "disk": 4000, "d1b": 2500, "assembly": 3500}
#: The test types of a campaign.
TEST_TYPES = ("blade", "disk", "d1b", "assembly")


def default_known_joints(n_blades: int) -> tuple[int, ...]:
    """Filmed joints when none are given: up to 5 (paper §6.1), spread evenly, never all of them."""
    n_known = min(5, max(2, n_blades // 3), n_blades - 1)
    known = np.unique(np.round(np.linspace(1, n_blades, n_known + 2)[1:-1]).astype(int))
    if known.size < n_known:  # few blades: interior positions round together (3 blades: 2 and 2), use the ends
        known = np.unique(np.round(np.linspace(1, n_blades, n_known)).astype(int))
    return tuple(int(k) for k in known)


@dataclass(frozen=True)
class CampaignSpec:
    """What to simulate. ``n_blades`` and ``grid`` default to the academic twin's (paper specimen).

    ``realism`` picks the truth twin (:data:`lab.truth.REALISM`): ``"realistic"`` (a specimen and a test that
    differ from the model as real ones do, docs/twin.md) or ``"ideal"`` (the model's own parts, for tests that
    isolate one stage); ``truth`` overrides it with parameters made in Python. ``coherence`` names the test
    types whose files carry the time-domain hammer test's coherence (ignored by the ideal twin's test).
    ``reseat`` names joints whose contact is drawn again (:func:`lab.patterns.redraw_joints`, both flanks'
    contact fraction near ``reseat_fraction`` where given): the seed's campaign after those blades were pulled
    and re-seated, for comparing re-assemblies. Only their contact changes; the tests whose band it moves, and
    those after them, draw their noise from the same stream but may draw it differently.
    """

    seed: int = 0
    n_blades: int = AcademicParams.n_blades
    grid: tuple[int, int] = AcademicParams.__dataclass_fields__["grid"].default
    level: str = "default"
    known_joints: tuple[int, ...] | None = None
    name: str = "academic"
    realism: str = "realistic"
    coherence: tuple[str, ...] = TEST_TYPES
    reseat: tuple[int, ...] = ()
    reseat_fraction: float | None = None
    truth: TruthParams | None = None
    pressure: PressureParams | None = None
    film: FilmParams = field(default_factory=FilmParams)
    max_lines: dict = field(default_factory=lambda: dict(MAX_LINES))

    def truth_params(self) -> TruthParams:
        """The twin's parameters: ``truth`` where given, else those of the ``realism`` setting."""
        return self.truth if self.truth is not None else TruthParams.of(self.realism)

    def pressure_params(self) -> PressureParams:
        """The contact-pressure generator: ``pressure`` where given, else that of the ``realism`` setting."""
        return self.pressure if self.pressure is not None else PressureParams.of(self.realism)

    def model_params(self) -> AcademicParams:
        """The academic-twin parameters (raises ``ValueError`` naming a bad blade count, grid or level)."""
        return AcademicParams.for_blades(self.n_blades, grid=tuple(self.grid), level=self.level)

    def command(self, out: str | Path) -> str:
        """The ``bladetwin lab simulate`` command that regenerates this campaign into ``out``.

        Only the command-line settings are spelled out; a spec with non-default truth, pressure, film or line
        settings (made in Python) cannot be regenerated from the command line, and says so.
        """
        cmd = (f"bladetwin lab simulate --out {out} --seed {self.seed} --blades {self.n_blades} "
               f"--grid {self.grid[0]}x{self.grid[1]} --level {self.level} --known {','.join(map(str, self.known()))}"
               f" --name {self.name} --realism {self.realism} --coherence {','.join(self.coherence) or 'none'}")
        custom = self != CampaignSpec(self.seed, self.n_blades, tuple(self.grid), self.level, self.known_joints,
                                      self.name, self.realism, tuple(self.coherence))
        return cmd + (" (plus settings made in Python: re-seated joints, truth, pressure, film or lines)"
                      if custom else "")

    def known(self) -> tuple[int, ...]:
        known = default_known_joints(self.n_blades) if self.known_joints is None else tuple(self.known_joints)
        bad = [k for k in known if isinstance(k, bool) or not isinstance(k, (int, np.integer))
               or not 1 <= k <= self.n_blades]
        if bad or not known or len(set(known)) != len(known):
            raise ValueError(f"known joints {list(known)}: expected distinct joint numbers in 1..{self.n_blades}")
        if len(known) < 2:  # `bladetwin run` refuses a campaign with fewer: the PCA sampler needs two films a flank
            raise ValueError(f"known joints {list(known)}: expected at least 2 filmed joints")
        return tuple(sorted(int(k) for k in known))


def assembly_solve_modes(n_blades: int) -> int:
    """The modes the full-assembly test's truth solve computes for ``n_blades`` blades.

    The test covers :data:`FULL_FAMILIES` blade-mode families and the disk modes among them; the solve goes
    half as far again plus 6 (:func:`solved_modes`), as every test's.
    """
    return solved_modes(FULL_FAMILIES * n_blades + DISK_MODES)


def solved_modes(n_wanted: int) -> int:
    """Modes a test's truth solve computes to cover ``n_wanted``: invisible (in-plane) modes interleave with
    them, and the modes above the band leave their residual effect at its upper edge."""
    return n_wanted + n_wanted // 2 + 6


@dataclass(frozen=True, eq=False)
class CampaignTwin:
    """A campaign's truth twin and the random streams its tests and films draw from (:func:`campaign_twin`).

    Attributes
    ----------
    twin : TruthTwin
    pressure : TruePressure
        The joints' true contact pressure (the films' source).
    patterns : tuple of ContactPattern
        The contact it implies, per joint (the films' state).
    rng_damping, rng_noise, rng_film : numpy.random.Generator
        The streams of the modal damping, the test noise and the film grain, untouched yet.
    disk_scale : float
        How much the disk was enlarged to hold the slots (``rom.academic.disk_scale_for``; 1: not).
    """

    twin: TruthTwin
    pressure: TruePressure
    patterns: tuple[ContactPattern, ...]
    rng_damping: np.random.Generator
    rng_noise: np.random.Generator
    rng_film: np.random.Generator
    disk_scale: float


def campaign_twin(spec: CampaignSpec, params: AcademicParams | None = None,
                  say: Callable[[str], None] | None = None) -> CampaignTwin:
    """The truth twin of ``spec``'s campaign, drawn from its seed exactly as :func:`simulate_campaign` draws it.

    The one place the seed's streams are spawned: :func:`simulate_campaign` and
    :func:`lab.truth_response.add_response_truth` (which rebuilds an existing campaign's twin) both call it, so
    the two twins are the same.

    Parameters
    ----------
    spec : CampaignSpec
    params : AcademicParams, optional
        ``spec.model_params()`` where already made.
    say : callable, optional
        Called with a one-line description of the twin.
    """
    params = spec.model_params() if params is None else params
    rng = np.random.default_rng(spec.seed)
    # Independent streams per purpose, so that changing one part (say, the film grain) leaves the others.
    rng_pressure, rng_truth, rng_damping, rng_noise, rng_film = rng.spawn(5)
    scale = disk_scale_for(params.n_blades)
    if say is not None:
        say(f"academic twin, level {params.level}, {params.n_blades} blades, grid {params.grid[0]}x{params.grid[1]}"
            + (f", disk enlarged ×{scale:.3g} to hold the slots" if scale != 1.0 else ""))
    bd = build_bladed_disk(params)
    u, v = flank_coordinates(bd)
    pressure = simulate_pressure(u, v, params.n_blades, rng_pressure, spec.pressure_params())
    if spec.reseat:  # a sixth stream, spawned after the five: every other draw of the seed stays as it was
        pressure = redraw_joints(pressure, spec.reseat, rng.spawn(1)[0], spec.reseat_fraction)
    patterns = tuple(pressure.patterns())
    node_pressure = np.stack([np.stack([pressure.pressure(s, f, u, v) for f in ("L", "R")])
                              for s in range(1, params.n_blades + 1)])
    twin = make_truth_twin(bd, patterns, rng_truth, spec.truth_params(), node_pressure)
    return CampaignTwin(twin, pressure, patterns, rng_damping, rng_noise, rng_film, scale)
