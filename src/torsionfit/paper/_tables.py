"""Tables 4 and 6 reproduced: each published value next to the paper's own evaluation of the
bundled SYNTHETIC run (data alone, as ``scripts/paper_tables.py`` and ``torsionfit metrics``)
and the 95 % HDI of the same quantity from the fitted model."""

import numpy as np

from ..report import summarise
from ..units import from_si, to_si
from ._posterior import secant_draws
from ._published import PUBLISHED, PUBLISHED_UNIT, PublishedValue

#: the data-only metric that is the paper's evaluation of each table
DATA_METRIC = {"table4": "stiffness_rated_from_start_Nm_per_deg", "table6": "kd_Nm_per_deg"}
#: how each table's value is read from the data and from the model
METHOD = {
    "table4": "secant T_r / (θ(T_r, end of step 5) − θ at the start of step 1), from the loop alone; "
              "HDI: the fitted model run through the five-step protocol at the run's loading rate",
    "table6": "T_r / TE(180°) against the encoders' zero, mean over ±2° of output angle, from the TE run "
              "alone; HDI: the fitted model's TE at 180° against its unloaded zero",
}


def reproduced_value(metrics_by_run: dict, p: PublishedValue) -> float:
    """The paper's evaluation (N·m/°) of ``p``'s run from ``{run: data-only metrics}``."""
    return float(metrics_by_run[p.run][DATA_METRIC[p.table]]["value"])


def model_draws(fit, p: PublishedValue, secants: dict | None = None) -> np.ndarray:
    """Posterior draws (N·m/°) of the model's value for ``p``'s condition; ``secants``: K_s
    draws (N·m/arcmin) already computed, by loading rate."""
    if p.table == "table4":
        k = secants[p.loading_rate_Nm_per_s] if secants else secant_draws(fit, p.loading_rate_Nm_per_s)[:, 0]
    else:
        column = [s.name for s in fit.metric_specs].index(f"kd_mean[{p.run}]")
        k = np.asarray(fit.metric_draws)[:, column]
    return from_si(to_si(np.asarray(k), "stiffness", "Nm/arcmin"), "stiffness", PUBLISHED_UNIT)


def table_row(p: PublishedValue, metrics_by_run: dict, fit=None, secants: dict | None = None) -> dict:
    """``{"reducer", "condition", "published", "reproduced", "hdi95", "unit", …}`` for ``p``;
    ``hdi95`` None without a fit."""
    got = reproduced_value(metrics_by_run, p)
    row = {"reducer": p.reducer, "condition": p.condition, "published": p.value_Nm_per_deg, "reproduced": got,
           "hdi95": None, "unit": "N·m/°", "relative_deviation": got / p.value_Nm_per_deg - 1.0,
           "run": f"{p.campaign}/{p.run}"}
    if fit is not None:
        s = summarise(model_draws(fit, p, secants))
        row.update(hdi95=s["hdi95"], model_mean=s["mean"],
                   published_in_hdi95=bool(s["hdi95"][0] <= p.value_Nm_per_deg <= s["hdi95"][1]))
    return row


def reproduce_tables(metrics_by_campaign: dict, fits: dict | None = None, secants: dict | None = None) -> dict:
    """``{"table4": rows, "table6": rows}`` in the paper's order; ``metrics_by_campaign``:
    ``{campaign: {run: metrics}}``, ``fits``: ``{campaign: CampaignFit}`` (optional),
    ``secants``: ``{campaign: {loading rate: K_s draws}}`` already computed (optional)."""
    fits, secants = fits or {}, secants or {}
    out = {"table4": [], "table6": []}
    for p in PUBLISHED:
        out[p.table].append(table_row(p, metrics_by_campaign[p.campaign], fits.get(p.campaign), secants.get(p.campaign)))
    return out
