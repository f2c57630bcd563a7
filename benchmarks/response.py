"""The forced response's intervals (issue 47): every EO × 200 posterior samples over families 1..3, against one
direct harmonic solve.

From a store that holds the run's full solves and posteriors (filled first if needed; warm after `make run`),
it times, for the exported (updated) ROM:

* **intervals**: for families 1..3 (bands from the tuned disk, refused or not; a family whose samples leave the
  perturbation's reach gets no interval, as in the run, and is not timed: ``n_families`` counts the timed ones),
  the tuned sweeps of every EO, then each of the posterior's 200 samples' AF at every EO
  (:func:`bladetwin.stages.response_intervals.family_interval`, as the run: the family's modes corrected per
  sample and a sweep per EO, once with the contact alone and once with the frequency and amplitude
  discrepancies, both passes counted in the time of a case);
* **reference, one case by a direct harmonic solve**: the same ROM assembled as the sparse hybrid (FE disk and
  Rubin blades, :func:`rom.rom_assembly.assemble_full`) and solved (K (1 + iη) − ω² M) x = F at
  ``--direct-lines`` frequencies of family 1's band under EO 1 (Pardiso, about 80 s a line on 172 458 DOFs);
  its time per line times the lines of the modal sweep of that case is the direct solve's time for one case (the
  lines are measured, the product estimated).

Target (issue 47): the intervals ≤ 60 s on 2 cores.

Run: ``.venv/bin/python benchmarks/response.py [CAMPAIGN] [--workers 2] [--direct-lines 1] [--json out.json]``
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import _paths  # noqa: F401  (puts the repository first on sys.path)
import numpy as np


def _inputs(campaign, workers: int) -> dict:
    from bladetwin.run import run_nodes
    from bladetwin.stages import RunOptions, names
    from rom.cache import default_cache_dir

    unfilmed = [t.index for t in campaign.of_type("d1b") if t.index not in campaign.known_joints]
    wanted = [names.full("updated"), names.RESPONSE_TUNED_UPDATED, names.RESPONSE_D1B_UPDATED, names.DELTA_ALL,
              names.FE_MODEL, names.BLADE_RUBIN, names.rom_update("answer"), names.posterior_patterns("experimental"),
              names.ema("assembly"), *[names.posterior_joint("experimental", j) for j in unfilmed],
              *[names.ema(names.test_name(t)) for t in campaign.of_type("d1b")]]
    print(f"filling {default_cache_dir()} with the run's solves and posteriors (warm after `make run`) ...",
          flush=True)
    res, _ = run_nodes(campaign, wanted, RunOptions(cache_dir=default_cache_dir(), workers=workers))
    out = {k: res[k] for k in wanted}
    out["posts"] = {j: res[names.posterior_joint("experimental", j)] for j in unfilmed}
    out["d1b_fits"] = {t.index: res[names.ema(names.test_name(t))] for t in campaign.of_type("d1b")}
    return out


def _direct_case(res, band, zeta: float, eo: int, n_lines: int) -> tuple[float, int]:
    """(seconds per frequency line of a direct sparse harmonic solve, DOFs) of the updated ROM under EO ``eo``.

    (K (1 + iη) − ω² M) x = F with η = 2ζ, as the real system [[A, −ηK], [ηK, A]] [Re x; Im x] = [F; 0],
    A = K − ω² M, by Pardiso (pypardiso, as the project's other sparse solves; SciPy's SuperLU took 18 GB).
    """
    import pypardiso
    import scipy.sparse as sp

    from bladetwin.stages import names
    from bladetwin.stages.rom_update import updated_parts
    from rom.rom_assembly import assemble_full

    blade, delta_all = updated_parts(res[names.BLADE_RUBIN], res[names.FE_MODEL], res[names.DELTA_ALL],
                                     res[names.rom_update("answer")])
    patterns = dict(enumerate(res[names.posterior_patterns("experimental")], start=1))
    asm = assemble_full(res[names.FE_MODEL], blade, patterns, delta_all)
    n_b = len(patterns)
    rows = {int(lab[1]): k for k, lab in enumerate(asm.meas_labels) if lab[0] == "blade" and int(lab[2]) == 1}
    out = asm.out.toarray() if hasattr(asm.out, "toarray") else np.asarray(asm.out)
    force = out[[rows[s] for s in range(1, n_b + 1)]].T @ np.exp(2j * math.pi * eo * np.arange(n_b) / n_b)
    K, M = asm.K.tocsr(), asm.M.tocsr()
    rhs = np.concatenate([force.real, force.imag])
    t = time.perf_counter()
    for f in np.linspace(*band, n_lines):
        A = K - (2 * math.pi * f) ** 2 * M
        x = pypardiso.spsolve(sp.bmat([[A, -2 * zeta * K], [2 * zeta * K, A]], format="csr"), rhs)
        assert np.all(np.isfinite(x))
    return (time.perf_counter() - t) / n_lines, int(K.shape[0])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=str(_paths.REPO / "measurements" / "academic"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--direct-lines", type=int, default=1,
                    help="frequency lines the direct reference solves (about 80 s each at the default level)")
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the figures to this JSON file")
    args = ap.parse_args(argv)

    from bladetwin.campaign import read_campaign
    from bladetwin.stages import names
    from bladetwin.stages.response import POINT, band_damping, measured_damping
    from bladetwin.stages.response_intervals import contact_samples, family_changes, family_interval
    from bladetwin.util import atomic_write_text
    from rom.errors import ROMError
    from rom.forced import blade_modes, family_band, forced_response

    campaign = read_campaign(args.campaign)
    res = _inputs(campaign, args.workers)
    measured = measured_damping({"assembly": res[names.ema("assembly")]})
    n = res[names.DELTA_ALL].shape[0]
    eos = tuple(range(n // 2 + 1))
    tun0 = blade_modes(res[names.RESPONSE_TUNED_UPDATED], 0.01, POINT)
    bands = np.array([family_band(tun0, fam) for fam in (1, 2, 3)])
    zeta = np.array([band_damping(b, *measured[:2]) for b in bands])
    # one ratio for every mode, the families' mean: overlapping bands (families 2 and 3 of the bundled updated ROM)
    # cannot each give theirs, and the timing only needs the sweeps' lines to be as many as the run's
    solved = res[names.full("updated")].modes
    mis = blade_modes(solved, np.full(solved.frequencies_hz.size, zeta.mean()), POINT)
    tun = blade_modes(res[names.RESPONSE_TUNED_UPDATED], np.full(tun0.n_modes, zeta.mean()), POINT)
    samples = contact_samples(n, res["posts"])
    test_hz = np.asarray(res[names.ema("assembly")].model.frequencies_hz, float)
    step = forced_response(mis, 1, tuple(bands[0])).step_hz  # family 1's sweep grid (its peak refinement aside)
    lines = int(np.ceil((bands[0][1] - bands[0][0]) / step)) + 1
    counted, t_int = 0, 0.0
    for fam, band in zip((1, 2, 3), bands, strict=True):
        t0 = time.perf_counter()
        refs = {e: forced_response(tun, eo, tuple(band)) for e, eo in enumerate(eos)}
        dl, psi, why = family_changes(samples, band, res[names.RESPONSE_D1B_UPDATED])
        if dl is None:
            # no tracked d1b mode in this family's band: time it on family 1's changes all the same
            dl, psi, _ = family_changes(samples, bands[0], res[names.RESPONSE_D1B_UPDATED])
            print(f"family {fam}: {why}; timed with family 1's sample changes", flush=True)
        try:
            family_interval(mis, tun, band, eos, refs, dl, psi, fam, test_hz, res[names.RESPONSE_D1B_UPDATED],
                            res["d1b_fits"])
        except ROMError as exc:  # as the run's node: no interval for this family, and here no time counted
            print(f"family {fam}: no interval ({exc}); not timed", flush=True)
            continue
        t_int += time.perf_counter() - t0
        counted += samples.n_samples * len(eos)
    if not counted:
        raise SystemExit("no family gave an interval: nothing timed")
    per_line, n_dof = _direct_case(res, bands[0], float(zeta[0]), 1, args.direct_lines)
    t_direct = per_line * lines
    n_fam = counted // (samples.n_samples * len(eos))
    figures = {"campaign": campaign.name, "workers": args.workers, "cpu_count": os.cpu_count(),
               "n_blades": n, "n_eo": len(eos), "n_families": n_fam, "n_samples": samples.n_samples,
               "n_cases": counted, "intervals_s": t_int, "per_case_ms": 1e3 * t_int / counted,
               "direct_dofs": n_dof, "direct_lines_solved": args.direct_lines, "direct_s_per_line": per_line,
               "direct_case_lines": int(lines), "direct_case_s": t_direct,
               "ratio_direct_case_to_modal_case": t_direct / (t_int / counted), "target_s": 60.0}
    print(f"{'what':<58}{'time [s]':>10}")
    print(f"{'direct harmonic solve, one case (reference, estimated)':<58}{t_direct:>10.1f}"
          f"   ({lines} lines × {per_line:.3f} s, {n_dof} DOFs, {args.direct_lines} lines measured)")
    print(f"{f'intervals: {len(eos)} EOs × {n_fam} families × {samples.n_samples} samples':<58}{t_int:>10.1f}"
          f"   ({1e3 * t_int / counted:.2f} ms a case, {t_direct / (t_int / counted):.0f}× faster than direct)")
    print(f"target: the intervals ≤ 60 s on 2 cores ({'met' if t_int <= 60 else 'NOT met'})")
    if args.json:
        atomic_write_text(args.json, json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
