"""Forced response of a bladed disk under engine-order excitation, and the mistuning amplification factor.

**Model.** A linear, viscously damped structure with real (or complex) normal modes φ_r, *mass-normalised over
the whole model* (φ_rᵀ M φ_r = 1, plain transpose, as :class:`rom.fe_assembly.AssemblyModes` and
:class:`rom.modal.DenseModes` give them; units m/√kg), natural frequencies ω_r = 2π f_r and modal damping
ratios ζ_r. Under a harmonic force F e^{iωt} the steady response is X e^{iωt} with, by modal superposition
over every mode of the model (those outside the sweep band included: they add their quasi-static share),

    X_j(ω) = Σ_r φ_jr (φ_rᵀ F) / (ω_r² − ω² + 2 i ζ_r ω_r ω)      (receptance, m for F in N),

which is exactly the solution of (K − ω² M + i ω C) X = F for modal damping C = M Φ diag(2 ζ_r ω_r) Φᵀ M
when Φ holds all the modes. ``form="mobility"`` gives i ω X (m/s), ``"accelerance"`` −ω² X (m/s²). Only the
shapes' rows at one DOF per blade are needed: the force acts there and the response is read there. The
normalisation matters mode by mode: shapes scaled otherwise (an EMA's unit-norm shapes) weight the modes
wrongly, and a common scale error, which cancels in the AF, still scales the peaks. Complex shapes are used
as given with φᵀ M φ = 1 (no conjugate); a real mode times a phase e^{iα} is not so normalised: pass the
real one.

**Engine-order excitation.** A travelling wave with engine order EO ∈ 0..⌊N/2⌋ on N blades: the same DOF of
every blade (in the blade's own frame) is loaded with F_j = F0 exp(i 2π EO (j − 1) / N), blades j = 1..N in
angular order (slot order). On a tuned disk it excites only the nodal-diameter-EO modes.

**Families and bands.** A sweep covers one mode family: a frequency band given by the caller, or
:func:`family_band`: the tuned disk's family k is, at each nodal diameter h (read from the shapes at the
blades, :func:`rom.solver.nodal_diameters`), the k-th lowest resonance (a degenerate pair counts once); its
band spans the family over all nodal diameters, widened by a relative margin for the mistuned modes that
leave it. The tuned family's resonance at the EO is that band's EO member.

**Sweep rule.** A uniform grid over the band with step Δf = min_r (2 ζ_r f_r) / ``points_per_bandwidth`` over
the model's modes inside the band (2 ζ_r f_r is mode r's half-power bandwidth; default 8 points in each),
then each blade's grid maximum refined between the grid neighbours of its maximum: Newton's method on
d|X_j|²/dω from the grid maximum, to a relative step of 1e-12; where a step leaves that bracket or meets a
convex stretch, a golden-section search of it (:data:`GOLDEN_ITERATIONS` steps shrink the bracket to 2e-7 Δf,
which leaves the peak's amplitude exact to round-off). Two grid steps are a quarter of a bandwidth, so the
bracket holds one peak unless two modes lie closer than that; the refined peak is never below the grid's
maximum.

**Amplification factor.** AF = max_j max_ω |X_j(ω)| on the mistuned disk over max_j max_ω |X_j(ω)| on the
tuned disk, same EO, force, band and damping. "The same damping" means per family, not per mode: mode-by-mode
EMA damping would make a tuned mode and its mistuned neighbours differ in damping as well as in stiffness
(:func:`family_damping` gives every mode its family's ratio). The tuned sweeps of every (family, EO) are
computed once for many mistuned models (:func:`tuned_references`). Whitehead (1966) bounds the AF by
(1 + √N)/2 for one isolated family with light damping (:func:`whitehead_limit`; D. S. Whitehead, "Effect of
mistuning on the vibration of turbo-machine blades induced by wakes", J. Mech. Eng. Sci. 8(1), 1966).
M. P. Castanier & C. Pierre,
"Modeling and analysis of mistuned bladed disk vibration: current status and emerging directions",
J. Propulsion Power 22(2), 2006, review it.

**What it is not.** Linear and structural only: no aerodynamic coupling (no aerodynamic damping or
stiffness, no flutter), no friction or contact nonlinearity, no backward-travelling (negative) engine
orders, no static or centrifugal pre-stress beyond what the modes already hold.

Modules: :mod:`.model` (the modes at the blades, the force, the receptance), :mod:`.sweep` (one band's
peaks), :mod:`.families` (bands and per-family damping), :mod:`.amplification` (the AF), :mod:`.perturbation`
(a family's modes under per-blade changes, for the intervals over posterior samples).
"""

from .amplification import AmplificationFactor, amplification_factor, amplification_factors, tuned_references
from .families import PAIR_RTOL, family_band, family_damping
from .model import FORMS, BladeModes, blade_modes, engine_order_force, modal_forces, receptance, whitehead_limit
from .perturbation import family_columns, perturbed_family, sample_model
from .sweep import GOLDEN_ITERATIONS, ForcedResponse, forced_response

__all__ = [
    "AmplificationFactor",
    "BladeModes",
    "ForcedResponse",
    "amplification_factor",
    "amplification_factors",
    "blade_modes",
    "engine_order_force",
    "family_band",
    "family_damping",
    "forced_response",
    "modal_forces",
    "family_columns",
    "perturbed_family",
    "sample_model",
    "receptance",
    "tuned_references",
    "whitehead_limit",
    "FORMS",
    "GOLDEN_ITERATIONS",
    "PAIR_RTOL",
]
