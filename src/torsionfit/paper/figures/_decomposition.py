"""Fig. 2: the loop split into its elastic, friction and geometric parts (and the creep that
makes the loop rate-dependent) by the fitted model, with 95 % posterior bands (paper Eq. 3)."""

import numpy as np

from ...plots import COMPONENT_STYLE
from ...units import from_si
from ._style import REDUCER_TITLE, band, figure, save

PARTS = ("elastic", "friction", "geometric", "creep")


def _arcmin(x):
    return from_si(np.asarray(x, float), "angle", "arcmin")


def fig02_decomposition(repro, out_dir):
    """Fig. 2: the measured loop and the posterior median; the parts along it with bands; the parts of the
    angle at T_r with their 95 % HDIs (large reducer)."""
    name = "paper-large"
    fit = repro.fit(name)
    run = min(fit.campaign.hysteresis_runs, key=lambda r: r.loading_rate_Nm_per_s)
    s = repro.settings
    comps = repro.run_components(name)[run.name]
    idx = comps["index"]
    tau = np.median(comps["drive_torque"], axis=0)
    offset = np.median(comps["offset"], axis=0)
    fig, axes = figure(3, width=5.0)
    ax_loop, ax_parts, ax_bar = axes[0]
    ax_loop.plot(np.asarray(run.torque_Nm)[idx], _arcmin(np.asarray(run.angle_rad)[idx] - offset), ".", ms=1.5, rasterized=True,
                 color="0.6", label="measured")
    band(ax_loop, tau, _arcmin(comps["total"] - comps["offset"]), "k", label="model, median and 95 % band")
    ax_loop.set_xlabel("torque (N·m)")
    ax_loop.set_ylabel("twist (arcmin, per-run offset removed)")
    ax_loop.legend(fontsize=7, markerscale=4, loc="upper left")
    ax_loop.set_title(f"loop at {run.loading_rate_Nm_per_s:g} N·m/s", fontsize=9)
    for part in PARTS:
        if part in comps and np.max(np.abs(comps[part])) > 0:
            color, label = COMPONENT_STYLE[part]
            band(ax_parts, tau, _arcmin(comps[part]), color, label=label)
    ax_parts.axhline(0, color="0.8", lw=0.5)
    ax_parts.set_xlabel("torque (N·m)")
    ax_parts.set_ylabel("part of the twist (arcmin)")
    ax_parts.legend(fontsize=7, loc="upper left")
    ax_parts.set_title("θ = θ_e + θ_f + θ_g (+ creep), Eq. (3)", fontsize=9)
    names = [sp.name for sp in fit.metric_specs]
    shown = [p for p in PARTS if f"twist_{p}_at_rated" in names]
    draws = np.stack([np.asarray(fit.metric_draws)[:, names.index(f"twist_{p}_at_rated")] for p in shown], axis=1)
    lo, mid, hi = np.percentile(draws, [2.5, 50, 97.5], axis=0)
    x = np.arange(len(shown))
    ax_bar.bar(x, mid, color=[COMPONENT_STYLE[p][0] for p in shown], alpha=0.7)
    ax_bar.errorbar(x, mid, yerr=[mid - lo, hi - mid], fmt="none", ecolor="k", capsize=4)
    for xi, m, l_, h in zip(x, mid, lo, hi):
        ax_bar.annotate(f"{m:.3f}\n[{l_:.3f}, {h:.3f}]", (xi, max(m, 0)), textcoords="offset points", xytext=(0, 4),
                        ha="center", fontsize=6)
    ax_bar.set_xticks(x, shown, fontsize=8)
    ax_bar.axhline(0, color="0.8", lw=0.5)
    ax_bar.set_ylabel("part of the angle at T_r (arcmin)")
    ax_bar.set_ylim(top=1.2 * max(hi))
    ax_bar.set_title(f"at T_r, end of step 5 of the model's loop at {run.loading_rate_Nm_per_s:g} N·m/s\n"
                     "median and 95 % HDI", fontsize=9)
    sampler = fit.diagnostics["sampler"]
    return save(fig, out_dir, "fig02_decomposition",
                f"Fig. 2 — composition of the hysteresis curve, {REDUCER_TITLE[name]}; posterior ({sampler}, "
                f"{s.band_draws} draws in the bands)")
