"""``diagnose.json`` (DESIGN §5.2) and the figures of a diagnosis."""

import json
import textwrap
from pathlib import Path

import numpy as np

from .._provenance import provenance
from .._x64 import in_float64
from ..units import ANGLE_UNITS
from ._loop import JUMPS, Diagnosis

ARCSEC = ANGLE_UNITS["arcsec"]


_NOTHING_LEFT = "nothing left that is large against the noise"


def _evidence(ev) -> dict:
    return {"effect": ev.effect, **ev.as_dict()}


def diagnose_json(d: Diagnosis, campaign) -> dict:
    def fitted(f):
        return {"effects": sorted(f.effects), "rmse": f.rmse_arcsec, "max_abs": f.max_abs_arcsec,
                "rmse_per_run": f.rmse_per_run, **f.score.as_dict()}

    return {
        "campaign": str(campaign.path) if campaign.path else None,
        "label": campaign.notes,
        "unit": "arcsec",
        "steps": [
            {"effect": s.effect, "evidence": _evidence(s.evidence),
             "rmse_before": s.before.rmse_arcsec, "rmse_after": s.after.rmse_arcsec,
             "max_abs_before": s.before.max_abs_arcsec, "max_abs_after": s.after.max_abs_arcsec,
             **s.comparison.as_dict()}
            for s in d.steps
        ],
        # the final model's: a growable effect may take two steps, and a later step may replace one
        "added": d.final_added(),
        # kept steps a later one took out in its place (the held gap the relays replace): effect → replacer
        "replaced": d.replaced(),
        "rejected": [
            {"effect": s.effect, "evidence": _evidence(s.evidence), "rmse_before": s.before.rmse_arcsec,
             "rmse_after": s.after.rmse_arcsec, **s.comparison.as_dict()}
            for s in d.rejected
        ],
        # each kept effect refitted out of a later model (DiagnoseOptions.backward): ΔELPD of keeping it
        "removals": [
            {"effect": r.effect, "dropped": r.dropped, "effects_with": sorted(r.within.effects),
             "rmse_with": r.within.rmse_arcsec, "rmse_without": r.without.rmse_arcsec, **r.comparison.as_dict(),
             # a swap: the effect refitted in its place, and that model's ΔELPD over the one with it
             **({"replaced_by": r.replaced_by, "swap_delta_elpd": r.swap_comparison.delta,
                 "swap_delta_elpd_se": r.swap_comparison.se} if r.replaced_by else {})}
            for r in d.removals
        ],
        "unexplained": d.unexplained,
        "unexplained_description": d.unexplained_description,
        "notes": list(d.notes),
        "noise_estimate": d.noise_arcsec,
        "signature_test": "least-squares and winsorised" if any(r.robust for r in d.final.context.runs) else "least-squares",
        "leftovers": [_evidence(e) for e in d.leftovers],
        "rmse_base": d.base.rmse_arcsec,
        "rmse_final": d.final.rmse_arcsec,
        "base": fitted(d.base),
        "final": fitted(d.final),
        "signatures": [[_evidence(e) for e in sigs] for sigs in d.signatures],
    }


def summary_text(doc: dict) -> str:
    lines = [f"base model: RMSE {doc['rmse_base']:.3g}″"]
    for s in doc["steps"]:
        lines.append(f"+ {s['effect']:24s} log10 p {s['evidence']['log10_p']:9.1f}   RMSE {s['rmse_before']:.3g}″ → "
                     f"{s['rmse_after']:.3g}″   max {s['max_abs_before']:.3g}″ → {s['max_abs_after']:.3g}″   "
                     f"ΔELPD {s['delta_elpd']:.1f} ± {s['delta_elpd_se']:.1f} ({s['criterion']})")
    for s in doc["rejected"]:
        lines.append(f"  {s['effect']:24s} tried, not kept: ΔELPD {s['delta_elpd']:.1f} ± {s['delta_elpd_se']:.1f} ({s['criterion']}), "
                     f"RMSE {s['rmse_before']:.3g}″ → {s['rmse_after']:.3g}″")
    for r in doc.get("removals", []):
        verdict = ("dropped, no longer earns its keep" if r["dropped"] else "checked, still earns its keep")
        if r.get("replaced_by"):
            verdict = (f"swapped out for {r['replaced_by']} (ΔELPD {r['swap_delta_elpd']:.1f} ± "
                       f"{r['swap_delta_elpd_se']:.1f} over the model with it), earned")
        lines.append(f"- {r['effect']:24s} {verdict}: ΔELPD {r['delta_elpd']:.1f} ± {r['delta_elpd_se']:.1f} "
                     f"({r['criterion']}) over the model without it, RMSE {r['rmse_without']:.3g}″ without it, "
                     f"{r['rmse_with']:.3g}″ with it")
    replaced = "".join(f"; {e} replaced by {by}" for e, by in doc.get("replaced", {}).items())
    lines.append(f"final: RMSE {doc['rmse_final']:.3g}″ (noise estimate {doc['noise_estimate']:.3g}″), "
                 f"effects added: {', '.join(doc['added']) or 'none'}{replaced}")
    if doc.get("final_metrics"):
        k = doc["final_metrics"].get("misfit_inflation", 1.0)
        widened = f", likelihood tempered by 1/{k:.3g} for misfit" if k > 1.0 else ""
        lines.append(f"final model's metrics (mean, 95 % HDI; {doc['final_metrics']['sampler']}{widened}):")
        for name, e in doc["final_metrics"]["metrics"].items():
            lo, hi = e["hdi95"]
            lines.append(f"  {name:34s} {e['mean']:11.5g}   [{lo:10.5g}, {hi:10.5g}]  {e['unit']}")
        lines += [f"  {label}: {doc['final_metrics'][key]}" for key, label in FINAL_NOTES if doc["final_metrics"].get(key)]
    lines.append("unexplained: " + (doc["unexplained_description"] if doc["unexplained"] else _NOTHING_LEFT))
    lines += [f"note: {n}" for n in doc.get("notes", [])]
    return "\n".join(lines)


#: fit.json's notes the final metrics carry, and the summary's label of each
FINAL_NOTES = (("metrics_off_data_note", "off the data"), ("friction_hook_note", "physics"),
               ("gap_segment_note", "physics"), ("relay_gap_note", "physics"), ("noise_note", "noise"),
               ("laplace_note", "laplace"), ("prior_dominated_note", "prior"))


# float64 here too: write_diagnosis (or a script) calls this after diagnose() has returned,
# outside its scope (in float32 the Laplace parts of the misfit widening mix int32 and int64
# indices, or truncate); the rest of the report reads what the fits computed
@in_float64
def final_metrics(d: Diagnosis, seed: int = 0) -> dict:
    """The final model's metrics and physical parameters with 95 % HDIs — the ``metrics`` and
    ``parameters`` blocks of ``fit.json``, made by the same code from the final fit's MAP and
    draws of its Laplace approximation (what ``torsionfit fit --sampler laplace --with …``
    reports for the effects diagnose chose), widened for the structure the final model leaves as
    ``fit`` widens it (``misfit_inflation``: the likelihood to the power 1/k)."""
    from ..fit._misfit import widen_for_misfit
    from ..report._pipeline import FitOptions, finish_fit, fit_json

    f = d.final
    # the trail compares fits under the plain likelihood; an interval is a claim about the
    # reducer, and where the residual keeps structure over whole ramps the data carry fewer
    # independent samples than their count (SYNTHETIC independent bench, twist-side loop:
    # k = 44, the plain interval of the loading stiffness missed the simulator's)
    problem, map_result = widen_for_misfit(f.map_result.problem, f.map_result)
    options = FitOptions(effects=dict(f.effects), sampler="laplace")
    doc = fit_json(finish_fit(f.context.campaign, options, problem.model, problem, map_result, seed))
    return {"effects": f.effects, "sampler": "laplace",
            "note": "95 % HDIs from draws of the Laplace approximation at the final model's MAP, widened for "
                    "misfit as `torsionfit fit` widens (misfit_inflation); for posterior intervals run "
                    "`torsionfit fit` with these effects (--with) and a sampler",
            "misfit_inflation": doc["diagnostics"]["misfit_inflation"],
            "metrics": doc["metrics"], "parameters": doc["parameters"],
            # the metrics the data read directly whose reading the final model's interval misses
            "metrics_off_data": doc["diagnostics"]["metrics_off_data"],
            **{key: doc["diagnostics"][key] for key, _ in FINAL_NOTES if key in doc["diagnostics"]}}


def write_diagnosis(d: Diagnosis, campaign, out_dir, seed: int = 0, command: str | None = None) -> dict:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = diagnose_json(d, campaign)
    doc["final_metrics"] = final_metrics(d, seed)
    doc["provenance"] = provenance(seed, command)  # command: the command line that made it
    (out / "diagnose.json").write_text(json.dumps(doc, indent=2))
    write_figures(d, campaign, out / "figures")
    return doc


# ----------------------------------------------------------------------------- figures


def _plt():
    import matplotlib.pyplot as plt  # the user's backend left alone (Agg by itself without a screen)

    return plt


def _residual_panels(axes, fitted, title):
    for ax, r in zip(axes, fitted.context.runs):
        x = r.time_s
        ax.plot(x, r.residual / ARCSEC, ".", ms=1, color="C0")
        ax.axhline(0, color="0.6", lw=0.5)
        ax.set_ylabel(f"{r.name}\n(arcsec)", fontsize=7)
        ax.tick_params(labelsize=6)
    # a final model with many effects names them all: wrapped to the panel (8 in wide in the final figure)
    axes[0].set_title(_title(f"{title}: RMSE {fitted.rmse_arcsec:.3g}″", width=100, lines=2), fontsize=8)
    axes[-1].set_xlabel("time (s)", fontsize=7)


def _binned(x, y, bins=30):
    edges = np.linspace(np.min(x), np.max(x), bins + 1)
    idx = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    centres = 0.5 * (edges[1:] + edges[:-1])
    means = np.array([np.mean(y[idx == i]) if np.any(idx == i) else np.nan for i in range(bins)])
    return centres, means


def plot_signature(ax, effect: str, fitted, evidence):
    """The residual view that points at ``effect`` (before the effect was added)."""
    ctx = fitted.context
    if effect == "kinematic_error":
        spectrum = evidence.details.get("spectrum", {})
        orders = np.array([int(k) for k in spectrum])
        stats = np.array([spectrum[k] for k in spectrum])
        ax.bar(orders, stats, width=0.8, color="C0")
        for k in evidence.details.get("orders_found", []):
            ax.axvline(k, color="C3", lw=0.6, ls="--")
        ax.set_xlabel("order (per output revolution)")
        ax.set_ylabel("Δχ² per order (2 dof)")
        ax.set_title("spectrum of the TE residual over output angle", fontsize=8)
    elif effect == "speed_dependence":
        for r in ctx.te:
            ax.errorbar(r.speed_rad_s * 60 / (2 * np.pi), np.mean(r.residual) / ARCSEC,
                        yerr=np.std(r.residual) / ARCSEC / np.sqrt(len(r.residual)), fmt="o",
                        color="C0" if r.direction > 0 else "C3")
        ax.set_xlabel("output speed (rpm); blue forward, red backward")
        ax.set_ylabel("mean TE residual (arcsec)")
        ax.set_title("residual level versus speed", fontsize=8)
    elif effect == "thermal_drift":
        for k, r in enumerate(ctx.runs):
            c, m = _binned(r.time_s, r.residual / ARCSEC)
            ax.plot(c, m, "o-", ms=2, lw=0.8, color=f"C{k % 10}", label=r.name)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("binned residual (arcsec)")
        ax.legend(fontsize=6)
        ax.set_title("residual versus time", fontsize=8)
    elif effect == "rate_dependence":
        for k, r in enumerate(ctx.hysteresis):
            c, m = _binned(r.mesh_torque_Nm, r.residual / ARCSEC, 40)
            ax.plot(c, m, "o-", ms=2, lw=0.8, color=f"C{k % 10}", label=f"{r.name} ({r.loading_rate_Nm_per_s} N·m/s)")
        ax.set_xlabel("mesh torque (N·m)")
        ax.set_ylabel("binned residual (arcsec)")
        ax.legend(fontsize=6)
        ax.set_title("residual versus torque, one curve per loading rate", fontsize=8)
    else:  # residual versus mesh torque
        for k, r in enumerate(ctx.runs):
            if r.kind != "hysteresis":
                continue
            ax.plot(r.mesh_torque_Nm, r.residual / ARCSEC, ".", ms=1, alpha=0.3, color=f"C{k % 10}")
            c, m = _binned(r.mesh_torque_Nm, r.residual / ARCSEC, 40)
            ax.plot(c, m, "-", lw=1.2, color=f"C{k % 10}", label=r.name)
        ax.set_xlabel("mesh torque (N·m)")
        ax.set_ylabel("residual (arcsec)")
        ax.legend(fontsize=6)
        ax.set_title("residual versus mesh torque", fontsize=8)
    ax.axhline(0, color="0.6", lw=0.5)


def _title(text: str, width: int, lines: int = 3) -> str:
    """``text`` wrapped to lines of ``width`` characters (about the figure's width at its title's
    font size: a longer line is cut off at both edges), at most ``lines`` of them."""
    return textwrap.fill(text, width, max_lines=lines, placeholder=" …")


def write_figures(d: Diagnosis, campaign, folder) -> list:
    plt = _plt()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    source = campaign.notes or "source not stated"
    paths = []
    n = len(d.base.context.runs)
    for i, s in enumerate(d.steps, start=1):
        fig = plt.figure(figsize=(12, 1.6 * n + 2.2), constrained_layout=True)
        grid = fig.add_gridspec(n, 3)
        before = [fig.add_subplot(grid[k, 0]) for k in range(n)]
        after = [fig.add_subplot(grid[k, 1]) for k in range(n)]
        _residual_panels(before, s.before, "before")
        _residual_panels(after, s.after, f"after adding {s.effect}")
        ax = fig.add_subplot(grid[:, 2])
        plot_signature(ax, s.effect, s.before, s.evidence)
        fig.suptitle(_title(f"step {i}: {s.effect} (log10 p {s.evidence.log10_p:.1f}, ΔELPD {s.delta_elpd:.0f} ± "
                            f"{s.delta_elpd_se:.0f}) — {source}", width=190), fontsize=8)
        path = folder / f"step-{i}-{s.effect}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    fig, axes = plt.subplots(n, 1, figsize=(8, 1.6 * n + 1), squeeze=False, constrained_layout=True)
    added = d.final_added()
    _residual_panels(axes[:, 0], d.final, "final model" + (f" (+ {', '.join(added)})" if added else " (base)"))
    # "nothing left" over a residual of jumps would read as a good fit: the title says it moves in jumps
    robust = any(r.robust for r in d.final.context.runs)
    jumps = ("; " + JUMPS + (", weighed down in the tests" if robust else ", counted as noise") + " (see the notes)"
             if any(n.startswith(JUMPS) for n in d.notes) else "")
    fig.suptitle(_title("unexplained: " + d.unexplained_description if d.unexplained else _NOTHING_LEFT + jumps,
                        width=150, lines=2) + "\n" + _title(source, width=150), fontsize=7)
    path = folder / "final-residuals.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    paths.append(path)
    return paths
