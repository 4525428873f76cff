"""The operating-envelope figure: P(K_d(τ, v) ≥ K_req) over torque × speed with the p_accept
contour and the requirement's region (the paper's Fig. 19 made probabilistic)."""

from pathlib import Path

import matplotlib.pyplot as plt  # the user's backend is left alone (no matplotlib.use on import)
from matplotlib.patches import Rectangle

from ._envelope import Envelope  # noqa: E402


def plot_envelope(e: Envelope, *, source: str, path=None):
    """Map of ``e.probability``; solid contour at p_accept, dashed at 1 − p_accept; the
    requirement's region as a box. ``source`` says where the data came from."""
    fig, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    mesh = ax.pcolormesh(e.torque_Nm, e.speed_rpm, e.probability, vmin=0.0, vmax=1.0, cmap="RdYlGn", shading="nearest")
    fig.colorbar(mesh, ax=ax, label=f"P(K_d ≥ {e.k_req:g} {e.unit})")
    levels = [(1.0 - e.p_accept, "--", f"{1 - e.p_accept:.3g}"), (e.p_accept, "-", f"{e.p_accept:g}")]
    for level, style, text in levels:
        if e.probability.min() < level < e.probability.max():
            cs = ax.contour(e.torque_Nm, e.speed_rpm, e.probability, levels=[level], colors="k", linestyles=style)
            ax.clabel(cs, fmt={level: text}, fontsize=8)
    (t0, t1), (v0, v1) = e.torque_range_Nm, e.speed_range_rpm
    ax.add_patch(Rectangle((t0, v0), t1 - t0, v1 - v0, fill=False, lw=1.5, ec="C0", label="required region"))
    ax.set_xlabel("load torque (N·m)")
    ax.set_ylabel("output speed (rpm)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"operating envelope: {e.requirement}\n"
                 f"contours: p_accept (solid), 1 − p_accept (dashed)\n{source}", fontsize=8)
    if path is not None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=120)
        plt.close(fig)
    return fig
