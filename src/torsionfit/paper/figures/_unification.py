"""Fig. 4 and Eq. (25): a TE point lies on the loop — K_d = K_s when both the speed and the
loading rate are zero. The measured loops and TE points, and the fitted model's two limits."""

import numpy as np

from ...units import from_si
from .._published import published
from ._style import REDUCER_TITLE, figure, save

SPEED_MARKERS = ("s", "^", "D")


def fig04_te_on_loop(repro, out_dir):
    """Fig. 4: near T_r, the slowest loop's loading branch, the TE(180°) at T_r of each speed, and the
    model's θ(T_r) at τ̇ → 0 and TE(180°) at v → 0 with 95 % intervals, for both reducers."""
    fig, axes = figure(2)
    for ax, name, reducer in zip(axes[0], ("paper-small", "paper-large"), ("small", "large")):
        campaign = repro.campaign(name)
        rated = campaign.reducer.rated_torque_Nm
        run = min(campaign.hysteresis_runs, key=lambda r: r.loading_rate_Nm_per_s)
        tau = np.asarray(run.torque_Nm)
        theta = from_si(np.asarray(run.angle_rad) - run.angle_rad[0], "angle", "arcmin")
        near = tau > 0.6 * rated
        ax.plot(tau[near], theta[near], ".", ms=1.5, color="0.6", rasterized=True, label=f"loop at {run.loading_rate_Nm_per_s:g} N·m/s (data)")
        metrics = repro.data_metrics(name)
        for marker, p in zip(SPEED_MARKERS, published("table6", reducer)):
            te = metrics[p.run]["te_180"]["value"]
            ax.plot([rated], [te], marker, mfc="none", ms=7, label=f"TE(180°) at {p.speed_rpm:g} rpm (data)")
        limits = repro.zero_rate_and_speed(name)
        for key, color, dx, text in (("ks0", "C0", -0.01, "model θ(T_r), τ̇ → 0"), ("kd0", "C3", 0.01, "model TE(180°), v → 0")):
            angle = rated / np.asarray(limits[key])
            lo, mid, hi = np.percentile(angle, [2.5, 50, 97.5])
            ax.errorbar([rated * (1 + dx)], [mid], yerr=[[mid - lo], [hi - mid]], fmt="o", color=color, capsize=4,
                        ms=4, label=f"{text}: {mid:.4g} [{lo:.4g}, {hi:.4g}] arcmin")
        ratio = np.asarray(limits["kd0"]) / np.asarray(limits["ks0"])
        lo, mid, hi = np.percentile(ratio, [2.5, 50, 97.5])
        ax.set_title(f"{REDUCER_TITLE[name]}\nmodel K_d(v→0) / K_s(τ̇→0) = {mid:.4f} [{lo:.4f}, {hi:.4f}] (Eq. 25 says 1)",
                     fontsize=8)
        ax.set_xlim(0.6 * rated, 1.03 * rated)
        ax.set_xlabel("output torque τ (N·m)")
        ax.set_ylabel("θ − θ_start, or TE against the encoders' zero (arcmin)")
        ax.legend(fontsize=6, loc="upper left", markerscale=1)
    return save(fig, out_dir, "fig04_te_on_loop", "Fig. 4 — does a TE point lie on the loop? (Eq. 25)")
