"""``tables.json``: the reproduction as one JSON document — Tables 4 and 6 (published,
reproduced, model HDI), the polynomial H with its coefficients, Eq. (25) in the model, the
reference-angle question, the Fig. 19 decisions, the paper's inconsistencies and the settings."""

import dataclasses

import numpy as np

from ..report import summarise
from ._checks import inconsistencies
from ._published import CAMPAIGNS, CITATION, SYNTHETIC_LABEL
from ._tables import reproduce_tables

ARCMIN_PER_DEG = 60.0


def _per_deg_summary(draws_Nm_per_arcmin) -> dict:
    return {**summarise(np.asarray(draws_Nm_per_arcmin) * ARCMIN_PER_DEG), "unit": "N·m/°"}


def polynomial_entry(poly, grid, quantity: str, seed: int) -> dict:
    """H = τ / P(τ, v) for ``quantity`` ("kd" or "kt"): its coefficients and the grid it was fitted to."""
    key = "kd_Nm_per_arcmin" if quantity == "kd" else "kt_Nm_per_arcmin"
    te = "TE(180°)" if quantity == "kd" else "revolution-mean TE"
    return {
        "form": f"{'K_d' if quantity == 'kd' else 'K_t'} = τ / P(τ, v), P = {te} = Σ c_ij (τ/τ_s)^i (v/v_s)^j",
        "degrees": {"torque": poly.degrees[0], "speed": poly.degrees[1], "chosen_by": "BIC"},
        "scales": {"torque_Nm": poly.torque_scale_Nm, "speed_rpm": poly.speed_scale_rpm},
        "residual_sd_arcmin": poly.sigma, "n_points": poly.n_points, "dof": poly.dof,
        "coefficients": poly.coefficients(seed=seed),
        "grid": {"torque_Nm": grid.torque_Nm.tolist(), "speed_rpm": grid.speed_rpm.tolist(),
                 "stiffness_Nm_per_deg": (getattr(grid, key) * ARCMIN_PER_DEG).tolist(),
                 "description": "stiffness[i][j] at speed_rpm[i], torque_Nm[j]: TE runs on the virtual bench, "
                                "evaluated from the data alone"},
    }


def _reference_angle(metrics_by_run: dict) -> list[dict]:
    """TABLES.md note 4: the secant K_s depends on the reference angle; the elastic slope is neither."""
    out = []
    for run, m in metrics_by_run.items():
        if "stiffness_rated_from_start_Nm_per_deg" in m:
            out.append({"run": run, "start_of_step_1": m["stiffness_rated_from_start_Nm_per_deg"]["value"],
                        "loop_midpoint_at_zero_torque": m["stiffness_rated_Nm_per_deg"]["value"],
                        "elastic_slope": m["stiffness_elastic"]["value"] * ARCMIN_PER_DEG, "unit": "N·m/°"})
    return out


def _decision_entry(decision) -> dict:
    return {"decision": decision.decision, "p_conform": decision.p_conform, "reason": decision.reason,
            "consumer_risk": decision.consumer_risk, "producer_risk": decision.producer_risk}


def _fit_entry(fit) -> dict:
    d = fit.diagnostics
    return {"runs": [r.name for r in fit.campaign.runs], "effects": fit.options.effects,
            "posterior": d.get("posterior", "sampled" if d["sampler"] != "laplace" else "laplace"),
            "posterior_reason": d.get("posterior_reason", ""),
            "decimate": fit.options.decimate, "diagnostics": fit.diagnostics,
            "rmse_arcsec": fit.rmse_arcsec, "label": fit.campaign.notes}


def paper_document(repro) -> dict:
    """Everything ``tables.json`` holds, computed from ``repro`` (a :class:`Reproduction`)."""
    names = tuple(CAMPAIGNS.values())
    metrics = {n: repro.data_metrics(n) for n in names}
    fits = {n: repro.fit(n) for n in names}
    secants = {n: dict(zip(repro.secant_rates(n), repro.secants(n).T)) for n in names}
    tables = reproduce_tables(metrics, fits, secants)
    rows = tables["table4"] + tables["table6"]
    seed = repro.settings.seed
    eq25 = {}
    for n in names:
        lim = repro.zero_rate_and_speed(n)
        eq25[n] = {"ks_zero_rate": _per_deg_summary(lim["ks0"]), "kd_zero_speed": _per_deg_summary(lim["kd0"]),
                   "ratio_kd_to_ks": summarise(np.asarray(lim["kd0"]) / np.asarray(lim["ks0"]))}
    spec = repro.spec()
    requirement = spec.requirements[0]
    return {
        "label": f"{SYNTHETIC_LABEL}: the bundled campaigns data/paper-small and data/paper-large, made by the "
                 "virtual bench (data/calibrate.py); the paper's raw data were not published",
        "source": CITATION,
        "campaigns": {n: repro.campaign(n).notes for n in names},
        "settings": repro.settings.as_dict(),
        "table4": tables["table4"],
        "table6": tables["table6"],
        "max_relative_deviation": max(abs(r["relative_deviation"]) for r in rows),
        "polynomial": {n: {q: polynomial_entry(repro.polynomial(n, q), repro.grid(n), q, seed) for q in ("kd", "kt")}
                       for n in names},
        "eq25": eq25,
        "reference_angle": {n: _reference_angle(metrics[n]) for n in names},
        "acceptance": {
            "requirement": {"name": requirement.name, "min": requirement.limit, "unit": requirement.unit,
                            "torque_Nm": list(requirement.torque_range_Nm),
                            "speed_rpm": list(requirement.speed_range_rpm), "p_accept": spec.p_accept},
            "normal": _decision_entry(repro.acceptance("normal")[0]),
            "worn": {**_decision_entry(repro.acceptance("worn")[0]), "label": repro.worn_campaign().notes},
        },
        "inconsistencies": [dataclasses.asdict(c) for c in inconsistencies()],
        "fits": {**{n: _fit_entry(fits[n]) for n in names}, "worn": _fit_entry(repro.worn_fit())},
    }
