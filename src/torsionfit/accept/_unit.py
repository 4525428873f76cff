"""One unit: fit its campaign, decide against a spec, write ``accept.json`` (DESIGN §5.2)."""

import json
import logging
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._errors import InputError
from .._provenance import provenance
from .._x64 import in_float64
from ..fit import check_fittable
from ..report._against_data import off_data_note
from ..report import FitOptions, campaign_model, derived_metrics_for, fit_campaign, metrics_against_data, summarise
from ._conformance import conformance, requirement_quantities
from ._decision import Decision, decide_unit
from ._envelope import Envelope, envelope_axes, operating_envelope
from ._extrapolation import ExtrapolationWarning, extrapolation
from ._spec import Spec, bind_requirements

#: progress lines (INFO); the command line shows them on stderr unless --quiet
log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class UnitAcceptance:
    """A unit's decision with everything behind it: the fit, each requirement's quantity per
    draw (``quantities``, metric units) and the operating envelopes of its ``kd`` requirements."""

    spec: Spec
    bound: tuple
    fit: object  # report.CampaignFit
    quantities: np.ndarray  # (draws, requirements)
    decision: Decision
    envelopes: tuple[Envelope, ...]
    seed: int
    #: per requirement: the line saying which conditions the decision extrapolates to, or None
    extrapolations: tuple = ()


@in_float64
def bind_to_campaign(spec: Spec, campaign, options: FitOptions = FitOptions()):
    """(``BoundRequirement``s, ``DerivedMetrics``) of ``spec`` for ``campaign`` fitted with
    ``options`` — checked before any fit, so a wrong metric or unit fails at once."""
    check_fittable(campaign)  # e.g. no [reducer].rated_torque_Nm: one line, not a TypeError
    derived = derived_metrics_for(campaign, campaign_model(campaign, options), options.lost_motion_pct)
    return bind_requirements(spec, derived.specs, bool(campaign.te_runs)), derived


def _bound_to_fit(spec: Spec, bound, fit, campaign):
    """``bound`` with its columns in ``fit.metric_draws`` (a metric the fit could not read,
    ``diagnostics.metrics_not_computed``, is left out of them); a requirement on such a metric
    stops with one line naming the unit, the requirement and why."""
    not_computed = fit.diagnostics.get("metrics_not_computed") or {}
    for b in bound:
        if b.requirement.metric in not_computed:
            raise InputError(f"{campaign.path or campaign.reducer.name}: {b.requirement.where}: "
                             f"{b.requirement.metric} is not computed for this unit ({not_computed[b.requirement.metric]})")
    return bind_requirements(spec, fit.metric_specs, bool(campaign.te_runs))


@in_float64
def accept_campaign(campaign, spec: Spec, options: FitOptions = FitOptions(), seed: int = 0,
                    envelope: bool = True, fit=None) -> UnitAcceptance:
    """Fit ``campaign`` (``options``, ``seed``) and decide against ``spec``; with ``envelope``,
    also map P(K_d ≥ K_req) over torque × speed for every ``kd`` requirement. ``fit``: a
    ``CampaignFit`` of this campaign with these options already made (``torsionfit.batch``).
    A ``kd`` requirement whose region leaves the measured TE loads or speeds gives an
    :class:`ExtrapolationWarning` (one line, which conditions) and a note in ``accept.json``."""
    bound, derived = bind_to_campaign(spec, campaign, options)
    extrapolations = tuple(extrapolation(b.requirement, campaign) for b in bound)
    for line in filter(None, extrapolations):
        warnings.warn(line, ExtrapolationWarning, stacklevel=3)  # 3: past the float64 wrapper
    log.info("%s: %d runs, %d requirements%s", campaign.path or campaign.reducer.name, len(campaign.runs),
             len(bound), "" if fit is None else "; fitted already")
    fit = fit_campaign(campaign, options, seed=seed) if fit is None else fit
    bound = _bound_to_fit(spec, bound, fit, campaign)
    quantities = requirement_quantities(bound, derived, fit.metric_values, fit.metric_draws)
    d = fit.diagnostics
    # a requirement on a metric the data read directly, whose reading the model's interval
    # misses: the model is confidently wrong there, and no decision is made from it
    metrics, off = metrics_against_data(fit)
    off_required = sorted({b.requirement.metric for b in bound} & set(off))
    withheld = off_data_note(metrics, off_required) if off_required else ""
    decision = decide_unit(conformance(bound, quantities), [b.requirement.name for b in bound], spec.p_accept,
                           converged=bool(d["converged"]), not_converged_reason=d.get("reason", ""),
                           withheld_reason=withheld)
    envelopes = ()
    if envelope:
        reducer = campaign.reducer
        max_speed = max([reducer.max_speed_rpm or 0.0] + [r.speed_rpm for r in campaign.te_runs])
        envelopes = tuple(
            operating_envelope(derived, fit.metric_values, b, spec.p_accept,
                               *envelope_axes(reducer.rated_torque_Nm, max_speed, b.requirement.torque_range_Nm,
                                              b.requirement.speed_range_rpm))
            for b in bound if b.requirement.is_kd)
    return UnitAcceptance(spec, bound, fit, quantities, decision, envelopes, seed, extrapolations)


def _requirement_entry(b, quantity: np.ndarray, p: float, decision: str, extrapolates: str | None) -> dict:
    r = b.requirement
    entry = {
        "name": r.name, "p_conform": p, "decision": decision, "limit": r.limit, "unit": r.unit,
        "extrapolates": extrapolates,
        "metric": r.metric, "bound": r.bound,
        "limit_in_metric_unit": b.limit_in_metric_unit, "metric_unit": b.metric_unit,
        "posterior": {**summarise(quantity), "unit": b.metric_unit},
    }
    if r.is_kd:
        entry["torque_Nm"] = list(r.torque_range_Nm)
        entry["speed_rpm"] = list(r.speed_range_rpm)
        entry["posterior"]["description"] = "smallest K_d over the region, both directions"
    return entry


def envelope_json(e: Envelope) -> dict:
    return {
        "requirement": e.requirement, "k_req": e.k_req, "unit": e.unit, "p_accept": e.p_accept,
        "torque_Nm": e.torque_Nm.tolist(), "speed_rpm": e.speed_rpm.tolist(),
        "probability": e.probability.tolist(),
        "region": {"torque_Nm": list(e.torque_range_Nm), "speed_rpm": list(e.speed_range_rpm)},
        "description": "probability[i][j] = P(K_d >= k_req) at speed_rpm[i], torque_Nm[j]; "
                       "K_d = T / TE(180°) of the model, the smaller of the two directions",
    }


def accept_json(result: UnitAcceptance, command: str | None = None) -> dict:
    """The ``accept.json`` document (DESIGN §5.2); ``command``: the command line recorded in
    its provenance."""
    d, fit = result.decision, result.fit
    campaign = fit.campaign
    return {
        "decision": d.decision,
        "p_conform": d.p_conform,
        "p_accept": d.p_accept,
        "consumer_risk": d.consumer_risk,
        "producer_risk": d.producer_risk,
        "risk_is_upper_bound": d.risk_is_bound,
        "reason": d.reason,
        "extrapolates": [line for line in result.extrapolations if line],
        "requirements": [_requirement_entry(b, q, p, dec, x) for b, q, p, dec, x in
                         zip(result.bound, result.quantities.T, d.requirement_p_conform, d.requirement_decisions,
                             result.extrapolations or (None,) * len(result.bound))],
        "envelope": [envelope_json(e) for e in result.envelopes],
        "campaign": str(campaign.path) if campaign.path else None,
        "label": campaign.notes,
        "reducer": {"name": campaign.reducer.name, "rated_torque_Nm": campaign.reducer.rated_torque_Nm},
        "spec": {"path": str(result.spec.path) if result.spec.path else None, "label": result.spec.label,
                 "p_accept": result.spec.p_accept},
        "n_draws": d.n_draws,
        "seed": result.seed,
        "diagnostics": fit.diagnostics,
        "provenance": provenance(result.seed, command),
    }


def write_accept(result: UnitAcceptance, out_dir, figures: bool = True, command: str | None = None) -> dict:
    """Write ``out_dir/accept.json`` (and with ``figures`` the envelope maps in
    ``out_dir/figures/``); return the document. ``command``: recorded in its provenance."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = accept_json(result, command)
    (out / "accept.json").write_text(json.dumps(doc, indent=2))
    if figures and result.envelopes:
        from ._figure import plot_envelope

        for i, e in enumerate(result.envelopes):
            plot_envelope(e, source=result.fit.campaign.notes or "source not stated",
                          path=out / "figures" / f"envelope-{i}.png")
    return doc


def summary_text(doc: dict) -> str:
    """A few lines for the terminal: the decision, p_c per requirement, the reason."""
    lines = [f"{doc['reducer']['name']}: {doc['decision'].upper()}  (joint p_c {doc['p_conform']:.4g}, "
             f"p_accept {doc['p_accept']:g})"]
    for r in doc["requirements"]:
        lines.append(f"  {r['name']:48s} p_c {r['p_conform']:.4g}  {r['decision']}")
    lines.append(f"  {doc['reason']}")  # with the specific risk of an accepted or rejected unit
    lines += [f"  note: {line}" for line in doc.get("extrapolates", [])]
    if doc.get("label"):
        lines.append(f"  data: {doc['label']}")
    return "\n".join(lines)
