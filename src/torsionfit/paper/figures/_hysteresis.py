"""Figures of the hysteresis-curve method: the five-step protocol and its loop (Fig. 1), and
the loops at three loading rates (Figs. 11, 12), from the bundled runs alone."""

import numpy as np

from ...units import from_si
from .._published import published
from .._tables import reproduced_value
from ._style import REDUCER_TITLE, figure, save

STEP_COLORS = ("C0", "C1", "C2", "C3", "C4")
RATE_COLORS = ("C0", "C1", "C3")


def _arcmin(x):
    return from_si(np.asarray(x, float), "angle", "arcmin")


def _twist_from_start(run) -> np.ndarray:
    """θ − θ_start (arcmin), θ_start the first, unloaded sample (the paper's reference)."""
    angle = np.asarray(run.angle_rad, float)
    return _arcmin(angle - angle[0])


def fig01_protocol(repro, out_dir):
    """Fig. 1: torque over time with the five steps, and the loop they draw (large reducer,
    slowest loading rate), with the secant K_s = T_r / θ_r."""
    name = "paper-large"
    campaign = repro.campaign(name)
    run = min(campaign.hysteresis_runs, key=lambda r: r.loading_rate_Nm_per_s)
    rated = campaign.reducer.rated_torque_Nm
    step_s = rated / run.loading_rate_Nm_per_s
    t, tau, theta = np.asarray(run.time_s), np.asarray(run.torque_Nm), _twist_from_start(run)
    step = np.minimum((t / step_s).astype(int), 4)
    fig, axes = figure(2)
    ax_t, ax_loop = axes[0]
    label_level = (0.5, 0.5, -0.5, -0.5, 0.5)
    for k in range(5):
        sel = step == k
        ax_t.plot(t[sel], tau[sel], ".", ms=1, color=STEP_COLORS[k], rasterized=True)
        ax_t.text((k + 0.5) * step_s, label_level[k] * rated, f"({k + 1})", ha="center", fontsize=9, color=STEP_COLORS[k])
        ax_loop.plot(tau[sel], theta[sel], ".", ms=1, color=STEP_COLORS[k], label=f"step {k + 1}", rasterized=True)
    ax_t.axhline(0, color="0.8", lw=0.5)
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel("output torque τ (N·m)")
    ax_t.set_title(f"input locked; output loaded 0 → +T_r → 0 → −T_r → 0 → +T_r at {run.loading_rate_Nm_per_s:g} N·m/s",
                   fontsize=8)
    k_s = reproduced_value(repro.data_metrics(name), published("table4", "large")[0])
    theta_r = rated / (k_s / 60.0)
    ax_loop.plot([0, rated], [0, theta_r], "k--", lw=0.8, label=f"secant K_s = T_r / θ_r = {k_s:.1f} N·m/°")
    ax_loop.plot([rated], [theta_r], "ko", ms=4)
    ax_loop.annotate("(T_r, θ_r)", (rated, theta_r), textcoords="offset points", xytext=(-55, 4), fontsize=8)
    ax_loop.axhline(0, color="0.8", lw=0.5)
    ax_loop.axvline(0, color="0.8", lw=0.5)
    ax_loop.set_xlabel("output torque τ (N·m)")
    ax_loop.set_ylabel("output angle θ − θ_start (arcmin)")
    ax_loop.legend(fontsize=7, markerscale=6, loc="upper left")
    ax_loop.set_title("the loop; θ_start: unloaded, before step 1 (the paper's reference)", fontsize=8)
    return save(fig, out_dir, "fig01_protocol", f"Fig. 1 — hysteresis-curve method, {REDUCER_TITLE[name]}, run {run.name}")


def _loops(repro, out_dir, name: str, reducer: str, number: int):
    campaign = repro.campaign(name)
    rated = campaign.reducer.rated_torque_Nm
    values = published("table4", reducer)
    fig, axes = figure(2)
    ax, zoom = axes[0]
    for color, p in zip(RATE_COLORS, values):
        run = next(r for r in campaign.hysteresis_runs if r.name == p.run)
        tau, theta = np.asarray(run.torque_Nm), _twist_from_start(run)
        got = reproduced_value(repro.data_metrics(name), p)
        label = f"{p.condition}: K_s {got:.5g} N·m/° (published {p.value_Nm_per_deg:g})"
        for a in (ax, zoom):
            a.plot(tau, theta, ".", ms=1, color=color, label=label, rasterized=True)
        theta_r = rated / (got / 60.0)
        zoom.plot([rated], [theta_r], "o", mfc="none", color=color, ms=8)
    zoom.set_xlim(0.9 * rated, 1.01 * rated)
    top = [rated / (reproduced_value(repro.data_metrics(name), p) / 60.0) for p in values]
    span = max(top) - min(top)
    zoom.set_ylim(min(top) - 1.5 * span - 0.05 * max(top), max(top) + 0.5 * span)
    for a in (ax, zoom):
        a.set_xlabel("output torque τ (N·m)")
        a.set_ylabel("θ − θ_start (arcmin)")
    ax.legend(fontsize=7, markerscale=6, loc="upper left")
    ax.set_title("three loading rates (Table 3)", fontsize=9)
    zoom.set_title("near T_r: faster loading, smaller angle, higher K_s (circles: θ_r)", fontsize=9)
    return save(fig, out_dir, f"fig{number}_loops_{reducer}",
                f"Fig. {number} — static stiffness test results, {REDUCER_TITLE[name]}")


def fig11_loops_small(repro, out_dir):
    """Fig. 11: the small reducer's loops at 0.02, 0.05 and 0.1 N·m/s, K_s of each (Table 4)."""
    return _loops(repro, out_dir, "paper-small", "small", 11)


def fig12_loops_large(repro, out_dir):
    """Fig. 12: the large reducer's loops at 1, 2.5 and 5 N·m/s, K_s of each (Table 4)."""
    return _loops(repro, out_dir, "paper-large", "large", 12)
