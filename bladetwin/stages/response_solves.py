"""The solves the amplification factors need beyond the run's full-assembly solves (:mod:`.response`).

Each ROM's tuned disk and its disk–one-blade modes, and the truth twin's modes on a virtual campaign: nodes of
their own, so that they solve beside other work.
"""

from __future__ import annotations

import numpy as np

from .full import solve_assembly
from .rom_update import updated_parts

__all__ = ["D1B_MODES", "TRUTH_FILE", "tuned_node", "d1b_node", "truth_node"]

#: Modes of each ROM's disk–one-blade solve (:func:`d1b_node`), and the truth's file in a campaign's truth/.
D1B_MODES, TRUTH_FILE = 10, "response_modes.npz"


def tuned_node(cyclic, bd, blade, baseline, delta_all: np.ndarray, n_modes: int, update=None):
    """The node: a ROM's tuned disk, every joint with the pattern ``baseline`` and every blade the blades' mean
    (δ, and ε of ``update`` on its contact springs where the ROM was updated); its
    :class:`rom.fe_assembly.AssemblyModes`."""
    blade, delta_all = updated_parts(blade, bd, delta_all, update)
    mean = np.broadcast_to(np.mean(delta_all, axis=0), delta_all.shape).copy()
    return solve_assembly(cyclic, bd, blade, [baseline] * delta_all.shape[0], mean, n_modes).modes


def d1b_node(disk, blade, bd, baseline, delta_all: np.ndarray, update=None):
    """The node: a ROM's disk–one-blade modes with the pattern ``baseline`` and the blades' mean δ (and ε of
    ``update``, as :func:`tuned_node`): each family's blade mode ψ at the blade point, which scales the posterior
    samples' per-blade changes (:mod:`rom.forced.perturbation`)."""
    from rom.rom_assembly import solve_d1b

    blade, delta_all = updated_parts(blade, bd, delta_all, update)
    return solve_d1b(disk, blade, baseline, n_modes=D1B_MODES, delta=np.mean(delta_all, axis=0))


def truth_node(*, truth_dir: str, sha256: str) -> tuple:
    """The node: the truth twin's (mistuned, tuned) full-assembly modes at the blade points
    (:func:`lab.truth_response.load_response_truth`); ``sha256`` of the file keys it to its content."""
    from lab.truth_response import load_response_truth

    del sha256  # only the key's
    truth = load_response_truth(truth_dir)
    return truth.mistuned, truth.tuned
