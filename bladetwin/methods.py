"""summary.json's ``methods`` block and the posterior's table: each identification method's figures side by side.

Every figure is computed against the reference patterns (a virtual campaign's truth, or films of every joint),
on the unfilmed joints with a disk–one-blade test; none is available without references.
"""

from __future__ import annotations

import numpy as np

from identify.film_next import rank_film_next
from identify.posterior import WIDTH_NAMES, prior_intervals, width_ratio
from identify.validation import contact_area_fraction, contact_centroid, geometric_validation
from rom.academic import flank_coordinates

__all__ = ["methods_summary", "film_next", "posterior_rows", "POSTERIOR_HEADER", "posterior_frequency_rows",
           "FREQUENCY_HEADER"]

POSTERIOR_HEADER = ["joint", "area L (%)", "area L 5 %", "area L 95 %", "area R (%)", "area R 5 %", "area R 95 %",
                    "reference area L (%)", "reference area R (%)", "centroid u L (mm)", "u L 5 %", "u L 95 %",
                    "centroid v L (mm)", "v L 5 %", "v L 95 %", "centroid u R (mm)", "u R 5 %", "u R 95 %",
                    "centroid v R (mm)", "v R 5 %", "v R 95 %"]


def _unfilmed(res) -> list[int]:
    tested = {int(j) for j in res.joints}
    return [j for j in range(1, res.campaign.n_blades + 1) if j not in res.known and j in tested]


def _geometry(patterns: list, reference: list, joints: list[int], bd) -> dict:
    """Mean |area error| (pp), mean centroid distance (mm) and node agreement of ``patterns`` at ``joints``."""
    geo = geometric_validation([patterns[j - 1] for j in joints], [reference[j - 1] for j in joints], bd)
    agree = np.mean([np.mean(np.stack([patterns[j - 1].L, patterns[j - 1].R])
                             == np.stack([reference[j - 1].L, reference[j - 1].R])) for j in joints])
    return {"area_error_pp": float(np.mean(np.abs(geo.area_error_pct))),
            "centroid_distance_mm": float(1e3 * np.nanmean(geo.centroid_distance)), "node_agreement": float(agree)}


def _calibration(posts: dict, reference: list, joints: list[int], coords, features, feature_modes) -> dict:
    """The posterior's 90 % intervals and probability maps against the reference patterns.

    Coverage of the area (each flank), of the centroid (each flank's u and v, where the reference has contact)
    and of the feature frequencies: the ROM's with the reference pattern (``features.numerical_hz``), inside
    the interval of the ROM's over the posterior's samples; ``None`` where there is none to count.
    """
    inside, cen_in, freq_in, width, brier = [], [], [], [], []
    rows = {int(j): k for k, j in enumerate(features.joints)}
    feat = list(feature_modes) if features.numerical_hz is not None else []
    for j in joints:
        if j not in posts:
            continue
        p, ref = posts[j], np.stack([reference[j - 1].L, reference[j - 1].R])
        a = contact_area_fraction(ref)
        lo, hi = p.area_pct_ci90[:, 0], p.area_pct_ci90[:, 1]
        inside.extend(((lo <= a) & (a <= hi)).tolist())
        width.extend((hi - lo).tolist())
        brier.append(float(np.mean((p.probability - ref) ** 2)))
        c = contact_centroid(ref, *coords)  # (flank, u/v); NaN on a flank without contact
        ok = np.isfinite(c)
        cen_in.extend(((p.centroid_ci90[..., 0] <= c) & (c <= p.centroid_ci90[..., 1]))[ok].tolist())
        if feat and j in rows:
            f, (flo, fhi) = features.numerical_hz[rows[j]], p.frequencies_hz_ci90[feat].T
            freq_in.extend(((flo <= f) & (f <= fhi))[np.isfinite(f)].tolist())
    if not inside:
        return {}
    return {"ci90_coverage_area": float(np.mean(inside)), "ci90_median_width_pp": float(np.median(width)),
            "ci90_coverage_centroid": float(np.mean(cen_in)) if cen_in else None,
            "ci90_coverage_frequency": float(np.mean(freq_in)) if freq_in else None,
            "brier": float(np.mean(brier))}


def _width_ratio(posts: dict, widths: np.ndarray) -> dict:
    """Posterior over prior 90 % width (``widths``: :func:`identify.posterior.prior_intervals`) of each flank's area
    and centroid, median over the joints (1: the data say nothing about it)."""
    if not posts:
        return {}
    ratio = np.median([width_ratio(p, widths) for p in posts.values()], axis=0)
    return dict(zip(WIDTH_NAMES, (float(r) for r in ratio), strict=True))


def _area_width(posts: dict) -> float | None:
    """The median width (pp) of the posterior's 90 % area intervals over the joints and flanks: how sure the
    answer is, with or without a reference (the report's first screen quotes it)."""
    widths = [float(hi - lo) for p in posts.values() for lo, hi in np.asarray(p.area_pct_ci90)]
    return float(np.median(widths)) if widths else None


def _diagnostics(posts: dict) -> dict:
    """Each joint's chain figures (:class:`identify.chains.ChainDiagnostics`): R̂, ESS, steps, converged."""
    out = {}
    for j, p in sorted(posts.items()):
        d = getattr(p, "diagnostics", None)
        if d is not None:
            out[str(j)] = {"rhat": float(d.rhat), "ess": float(d.ess) if np.isfinite(d.ess) else None,
                           "n_steps": int(d.n_steps), "converged": d.converged}
    return out


def _cases(res, method: str) -> dict:
    c = res.cases
    if method == "knn":
        return {k: c.get(k) for k in ("A", "B", "C")} | {"baseline": c.get("baseline")}
    post = c.get("posterior") or {}
    return {"A": post.get("A"), "B": post.get("B"), "C": c.get("C"), "baseline": c.get("baseline")}


def methods_summary(res) -> dict:
    """``methods``: per method that ran, its cases and, per input, its geometry against the references."""
    joints = _unfilmed(res)
    out = {}
    for method, inputs in res.answers.items():
        entry: dict = {"cases": _cases(res, method)}
        for name, patterns in inputs.items():
            if res.reference is None or not joints:
                continue
            fig = _geometry(patterns, res.reference, joints, res.bd)
            if method == "posterior":
                fig |= _calibration(res.posterior.get(name, {}), res.reference, joints,
                                    flank_coordinates(res.bd), res.features, res.dataset.feature_modes)
            entry[name] = fig
        if method == "posterior":
            # what the data pin down needs no reference: every run reports it
            widths = prior_intervals(res.posterior["prior"], flank_coordinates(res.bd))
            entry["width_ratio"] = {name: _width_ratio(res.posterior.get(name, {}), widths) for name in inputs}
            entry["area_ci90_median_width_pp"] = {name: _area_width(res.posterior.get(name, {})) for name in inputs}
            entry["diagnostics"] = {name: _diagnostics(res.posterior.get(name, {})) for name in inputs}
            entry["film_next"] = film_next(res)
            s = res.posterior["surrogate"]
            entry["surrogate"] = {"error_pct": s.error_pct.tolist(), "max_error_pct": s.max_error_pct.tolist(),
                                  "n_train": s.n_train, "n_test": s.n_test}
            prior = res.posterior["prior"]
            entry["prior"] = {"n_components": list(prior.n_components), "level": prior.level.tolist(),
                              "level_std": prior.level_std.tolist(), "scale": prior.scale}
        out[method] = entry
    if res.reference is not None and joints:
        # the majority pattern on every joint, the bar both methods must clear
        out["baseline"] = _geometry([res.baseline_pattern] * res.campaign.n_blades, res.reference, joints, res.bd)
    return out


def film_next(res, input: str = "experimental") -> list[dict]:
    """``methods.posterior.film_next``: the unfilmed joints, best to film first (:func:`identify.film_next.
    rank_film_next`), each with ``joint``, ``outside_pp`` and ``width_pp``; empty without films or posteriors."""
    posts = res.posterior.get(input, {})
    if not posts or not res.known:
        return []
    joints = sorted(posts)
    answers = [res.answers["posterior"][input][j - 1] for j in joints]
    area = np.array([contact_area_fraction(np.stack([p.L, p.R])) for p in answers])
    films = np.array([contact_area_fraction(np.stack([p.L, p.R])) for p in res.known.values()])
    ranked = rank_film_next(joints, area, np.array([posts[j].area_pct_ci90 for j in joints]), films)
    return [{"joint": c.joint, "outside_pp": c.outside_pp, "width_pp": c.width_pp} for c in ranked]


def posterior_rows(res, input: str = "experimental") -> list[list]:
    """One row per unfilmed joint: the answer's areas with 90 % intervals, the reference's (NaN without one),
    centroids (mm)."""
    posts = res.posterior.get(input, {})
    u, v = flank_coordinates(res.bd)
    rows = []
    for j in sorted(posts):
        p = posts[j]
        pat = res.answers["posterior"][input][j - 1]
        grid = np.stack([pat.L, pat.R])
        area = contact_area_fraction(grid)
        cen = 1e3 * contact_centroid(grid, u, v)
        ref = (contact_area_fraction(np.stack([res.reference[j - 1].L, res.reference[j - 1].R]))
               if res.reference is not None else [np.nan, np.nan])
        row = [j]
        for s in (0, 1):
            row += [float(area[s]), float(p.area_pct_ci90[s, 0]), float(p.area_pct_ci90[s, 1])]
        row += [float(r) for r in ref]
        for s in (0, 1):
            for a in (0, 1):
                row += [float(cen[s, a]), *(1e3 * p.centroid_ci90[s, a]).tolist()]
        rows.append(row)
    return rows


FREQUENCY_HEADER = ["joint", "tracked mode", "measured, bias removed (Hz)", "answer (Hz)", "5 % (Hz)", "95 % (Hz)",
                    "answer − measured (%)"]


def posterior_frequency_rows(res) -> list[list]:
    """One row per unfilmed joint and tracked mode: the test's frequency (bias removed), the posterior's MAP
    prediction and its 90 % interval (experimental input); NaN where the test did not find the mode.

    The interval is the posterior's spread of the ROM's frequency, without the noise model's model error: a mode
    that does not feel the contact has a narrow interval however far the ROM is from the test."""
    posts = res.posterior.get("experimental", {})
    f = res.features
    joints = [int(j) for j in f.joints]
    rows = []
    for j in sorted(posts):
        p = posts[j]
        y = f.measured_hz[joints.index(j)] / (1 + f.bias) if j in joints else np.full(p.frequencies_hz.size, np.nan)
        for m, (yy, fm, (lo, hi)) in enumerate(zip(y, p.frequencies_hz, p.frequencies_hz_ci90, strict=True)):
            rows.append([j, m + 1, float(yy), float(fm), float(lo), float(hi), float(100 * (fm / yy - 1))])
    return rows
