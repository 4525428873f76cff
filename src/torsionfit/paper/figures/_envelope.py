"""Fig. 19: the normal surface P1 and the worn ("fault") surface P2 of the small reducer's K_d
over torque × speed, and where the worn unit still meets the requirement — as the probability
P(K_d ≥ K_req) from the acceptance module (``torsionfit.accept``), not a yes/no overlap."""

import numpy as np
from matplotlib import colormaps
from matplotlib.patches import Patch, Rectangle

from .._posterior import kd_draws
from ._style import figure, per_deg, save


def _median_surface(fit, torque_Nm, speed_rpm):
    t, v = np.meshgrid(torque_Nm, speed_rpm)
    k = np.median(kd_draws(fit, t.ravel(), v.ravel()), axis=0)
    return t, v, per_deg(k).reshape(t.shape)


def fig19_envelope(repro, out_dir):
    """Fig. 19: P1, P2 and the K_req plane; P(K_d,worn ≥ K_req) with the p_accept contours of both units."""
    decision_normal, env_normal = repro.acceptance("normal")
    decision_worn, env_worn = repro.acceptance("worn")
    k_req = env_worn.k_req
    fig = figure(1)[0]
    fig.clf()
    fig.set_size_inches(13.0, 5.2)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax = fig.add_subplot(1, 2, 2)
    fig.subplots_adjust(bottom=0.14, wspace=0.15)
    handles = []
    for fit, cmap, label in ((repro.fit("paper-small"), "Blues", "P1 normal"), (repro.worn_fit(), "Reds", "P2 worn")):
        t, v, k = _median_surface(fit, env_worn.torque_Nm, env_worn.speed_rpm)
        ax3.plot_surface(t, v, k, cmap=cmap, alpha=0.7, lw=0)
        # a legend, not text at a surface corner: there the label ran into the K_d tick labels
        handles.append(Patch(color=colormaps[cmap](0.7), label=label))
    t, v = np.meshgrid(env_worn.torque_Nm, env_worn.speed_rpm)
    ax3.plot_surface(t, v, np.full_like(t, k_req), color="0.5", alpha=0.3, lw=0)
    handles.append(Patch(color="0.5", alpha=0.3, label=f"K_req = {k_req:g} {env_worn.unit}"))
    ax3.legend(handles=handles, loc="upper left", fontsize=7)
    ax3.set_xlabel("τ (N·m)", fontsize=8)
    ax3.set_ylabel("v (rpm)", fontsize=8)
    ax3.set_zlabel("K_d (N·m/°)", fontsize=8)
    ax3.tick_params(labelsize=6)
    ax3.set_title(f"posterior median K_d(τ, v), forward; grey plane: K_req = {k_req:g} {env_worn.unit}", fontsize=8)
    mesh = ax.pcolormesh(env_worn.torque_Nm, env_worn.speed_rpm, env_worn.probability, vmin=0, vmax=1,
                         cmap="RdYlGn", shading="nearest")
    fig.colorbar(mesh, ax=ax, label=f"P(K_d ≥ {k_req:g} {env_worn.unit}), worn unit")
    for env, color, who in ((env_worn, "k", "worn"), (env_normal, "C0", "normal")):
        p = env.probability
        if p.min() < env.p_accept < p.max():
            cs = ax.contour(env.torque_Nm, env.speed_rpm, p, levels=[env.p_accept], colors=color)
            ax.clabel(cs, fmt={env.p_accept: f"{who}: P = {env.p_accept:g}"}, fontsize=7)
    (t0, t1), (v0, v1) = env_worn.torque_range_Nm, env_worn.speed_range_rpm
    ax.add_patch(Rectangle((t0, v0), t1 - t0, v1 - v0, fill=False, lw=1.5, ec="C0", ls="--"))
    ax.set_xlabel("load torque τ (N·m)")
    ax.set_ylabel("output speed v (rpm)")
    ax.set_title(f"dashed box: required region. Decisions (p_accept {env_worn.p_accept:g}): "
                 f"normal {decision_normal.decision} (p_c {decision_normal.p_conform:.3g}), "
                 f"worn {decision_worn.decision} (p_c {decision_worn.p_conform:.3g})\n"
                 "K_d at a condition: the smaller of forward and backward (torsionfit.accept)", fontsize=8)
    return save(fig, out_dir, "fig19_envelope", "Fig. 19 — normal and worn surfaces, and where the worn unit still meets "
                "the requirement")
