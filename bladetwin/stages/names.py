"""The catalog of ``bladetwin run``'s outputs: every node and source name, declared once (design §2.1).

:mod:`~bladetwin.stages.campaign_graph` adds its nodes under these names and wires their inputs with them;
whatever reads the runner's outputs (:func:`~bladetwin.stages.result.gather`, the stage commands, the timings'
groups) asks for them by the same constants and functions, never by a literal (``tests/pipeline/
test_stage_names.py`` checks it). The strings themselves key the store and ``summary.json``'s timings: they
never change.

Fixed names are constants (:data:`DATASET`, :data:`DISK_CB`…). A family of names is ``<family>/<member>``:
:func:`ema`, :func:`test_source`, :func:`full`, :func:`rom_update`, :func:`patterns`, :func:`posterior_patterns`,
:func:`refine`, :func:`posterior_joint` and :func:`posterior_part` build them, and :func:`member`,
:func:`members`, :func:`per_joint` and :func:`answer_of` read them back.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = [
    "CAMPAIGN", "FE_MODEL", "FE_NOMINAL", "STORE", "DASK",
    "BLADE_TABLE", "CALIBRATION", "DISK_CB", "BLADE_RUBIN", "DISK_CYCLIC", "DELTA_ALL",
    "FILMS", "KNOWN", "BASELINE", "REFERENCE", "SYNTHETIC", "SENSITIVITY", "DATASET", "FEATURES", "PREDICTIONS",
    "N_FULL_MODES", "VALIDATION", "D1B_ROWS", "RESPONSE", "RESPONSE_TUNED_PAPER", "RESPONSE_TUNED_UPDATED",
    "RESPONSE_D1B_PAPER", "RESPONSE_D1B_UPDATED", "RESPONSE_AF_PAPER", "RESPONSE_AF_UPDATED", "RESPONSE_TRUTH",
    "EMA", "TEST", "FULL", "ROM_UPDATE", "PATTERNS", "POSTERIOR", "REFINE", "FAMILIES",
    "PATTERNS_BASELINE", "POSTERIOR_PRIOR", "POSTERIOR_SURROGATE", "POSTERIOR_REPRESENTATION", "POSTERIOR_FACTORS",
    "POSTERIOR_CANDIDATES",
    "ROM_UPDATE_STIFFNESS",
    "test_name", "joint_key", "ema", "test_source", "full", "rom_update", "patterns", "posterior_patterns", "refine",
    "posterior_joint", "posterior_part", "member", "members", "per_joint", "answer_of",
]

# ------------------------------------------------------------------------------------------------ sources
#: The campaign (:class:`bladetwin.campaign.Campaign`).
CAMPAIGN = "campaign"
#: The FE model the stages use (calibrated where the run calibrates) and the one the calibration starts from.
FE_MODEL, FE_NOMINAL = "fe_model", "fe_nominal"
#: The store and the Dask settings, given to the nodes that need them (``@``: never a node's output).
STORE, DASK = "@store", "@dask"

# ------------------------------------------------------------------------------------------------ fixed nodes
BLADE_TABLE = "blade_table"
CALIBRATION = "calibration"
DISK_CB, BLADE_RUBIN, DISK_CYCLIC = "disk_cb", "blade_rubin", "disk_cyclic"
DELTA_ALL = "delta_all"
FILMS, KNOWN, BASELINE, REFERENCE = "films", "known", "baseline", "reference"
SYNTHETIC, SENSITIVITY, DATASET = "synthetic", "sensitivity", "dataset"
FEATURES, PREDICTIONS = "features", "predictions"
N_FULL_MODES, VALIDATION, D1B_ROWS = "n_full_modes", "validation", "d1b_rows"
#: The forced response and the amplification factors (:mod:`~bladetwin.stages.response`).
RESPONSE = "response"
#: Each ROM's tuned disk for the amplification factors: nodes of their own, so they solve beside other work.
RESPONSE_TUNED_PAPER, RESPONSE_TUNED_UPDATED = "response_tuned_paper", "response_tuned_updated"
#: The ROMs' disk–one-blade modes for the AF's intervals, and the truth twin's modes (virtual campaigns).
RESPONSE_D1B_PAPER, RESPONSE_D1B_UPDATED = "response_d1b_paper", "response_d1b_updated"
RESPONSE_TRUTH = "response_truth"
#: Each ROM's amplification factors: nodes of their own, so that the paper's ROM's runs beside the ROM update.
RESPONSE_AF_PAPER, RESPONSE_AF_UPDATED = "response_af_paper", "response_af_updated"

# ------------------------------------------------------------------------------------------------ families
#: The families' prefixes: every name of one is ``<prefix><member>``.
EMA, TEST, FULL, ROM_UPDATE = "ema/", "test/", "full/", "rom_update/"
PATTERNS, POSTERIOR, REFINE = "patterns/", "posterior/", "refine/"
FAMILIES = (EMA, TEST, FULL, ROM_UPDATE, PATTERNS, POSTERIOR, REFINE)

#: The posterior's answer for an input is ``patterns/posterior_<input>``, beside the k-NN's ``patterns/<input>``.
_POSTERIOR_ANSWER = "posterior_"
_JOINT = "joint_"


def test_name(t) -> str:
    """A test's name, the member of :func:`ema` and :func:`test`: its type, and its blade or joint number
    (``blade_03``, ``d1b_12``, ``disk``)."""
    return t.type if t.index is None else f"{t.type}_{t.index:02d}"


def joint_key(joint: int) -> str:
    """A joint's name in per-joint names and in the per-joint arguments of a node (``joint_07``)."""
    return f"{_JOINT}{joint:02d}"


def ema(test_name: str) -> str:
    """The EMA node of a test (``ema/blade_03``)."""
    return EMA + test_name


def test_source(test_name: str) -> str:
    """The source of a test's files (``test/d1b_12``)."""
    return TEST + test_name


def full(solve: str) -> str:
    """A full-assembly solve (``full/identified``, ``full/updated``…)."""
    return FULL + solve


def rom_update(name: str) -> str:
    """A node of the ROM update (``rom_update/stiffness``, ``rom_update/answer``…)."""
    return ROM_UPDATE + name


def patterns(input: str) -> str:
    """The k-NN's answer (one pattern per joint) for an input (``patterns/experimental``)."""
    return PATTERNS + input


def posterior_patterns(input: str) -> str:
    """The contact posterior's answer (one pattern per joint) for an input (``patterns/posterior_numerical``)."""
    return PATTERNS + _POSTERIOR_ANSWER + input


def refine(input: str, joint: int) -> str:
    """The refinement of one unfilmed joint for one input (``refine/experimental/joint_07``)."""
    return f"{REFINE}{input}/{joint_key(joint)}"


def posterior_joint(input: str, joint: int) -> str:
    """The contact posterior of one unfilmed joint for one input (``posterior/numerical/joint_07``)."""
    return f"{POSTERIOR}{input}/{joint_key(joint)}"


def posterior_part(part: int) -> str:
    """One part of the posterior's surrogate solves (``posterior/solves/part_0``)."""
    return f"{POSTERIOR}solves/part_{part}"


#: The answer of the baseline: the film at each filmed joint, the films' majority elsewhere.
PATTERNS_BASELINE = patterns(BASELINE)
POSTERIOR_PRIOR, POSTERIOR_SURROGATE = POSTERIOR + "prior", POSTERIOR + "surrogate"
POSTERIOR_REPRESENTATION, POSTERIOR_FACTORS = POSTERIOR + "representation", POSTERIOR + "factors"
#: Each unfilmed joint's plausible patterns (posterior draws) for the ROM update's consistency check.
POSTERIOR_CANDIDATES = POSTERIOR + "candidates"
ROM_UPDATE_STIFFNESS = rom_update("stiffness")


def member(name: str, family: str) -> str | None:
    """The member of ``name`` in ``family`` (one of :data:`FAMILIES`): ``member("full/updated", FULL)`` is
    ``"updated"``; ``None`` where ``name`` is not of that family."""
    return name[len(family):] if name.startswith(family) else None


def members(results: Mapping, family: str) -> dict[str, object]:
    """The outputs of one family by member, in the results' order (``{"identified": …, "baseline": …}``)."""
    return {m: results[k] for k in results if (m := member(k, family)) is not None}


def per_joint(name: str, family: str) -> tuple[str, int] | None:
    """(input, joint) of a per-joint name of ``family`` (:data:`REFINE` or :data:`POSTERIOR`): ``per_joint(
    "refine/numerical/joint_07", REFINE)`` is ``("numerical", 7)``; ``None`` for any other name."""
    rest = member(name, family)
    input, sep, joint = (rest or "").partition("/")
    if not sep or not joint.startswith(_JOINT) or "/" in joint:
        return None
    return input, int(joint.removeprefix(_JOINT))


def answer_of(name: str) -> tuple[bool, str] | None:
    """(whether the posterior's, input) of an answer's name (:func:`patterns`, :func:`posterior_patterns`);
    ``None`` where ``name`` is no answer."""
    rest = member(name, PATTERNS)
    if rest is None:
        return None
    return (True, rest.removeprefix(_POSTERIOR_ANSWER)) if rest.startswith(_POSTERIOR_ANSWER) else (False, rest)
