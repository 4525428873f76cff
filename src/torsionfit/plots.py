"""Figures. Every figure says where its data came from (measured, with the source, or
SYNTHETIC); angles in arcmin, torque in N·m."""

import matplotlib

matplotlib.use("Agg")  # files only: no screen on benches and CI
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .units import from_si  # noqa: E402

COMPONENT_STYLE = {
    "elastic": ("C0", "elastic  C(τ)"),
    "friction": ("C3", "friction (hysteresis)"),
    "geometric": ("C2", "geometric (lost motion)"),
    "creep": ("C1", "creep (rate dependence)"),
    "kinematic": ("C4", "kinematic"),
    "drift": ("C5", "drift"),
}


def _arcmin(x):
    return from_si(np.asarray(x, float), "angle", "arcmin")


def plot_loop_components(run, components: dict, *, source: str, drive_torque_Nm=None, path=None,
                         title: str | None = None):
    """Measured hysteresis loop with the model's total, and the model's components versus
    the torque driving the model (``drive_torque_Nm``: the denoised, latent-corrected torque;
    default the measured one). ``components`` are the model's per-sample arrays (rad), e.g.
    ``MapResult.components()[i]``; ``source`` names where the data came from."""
    measured_tau = np.asarray(run.torque_Nm)
    tau = measured_tau if drive_torque_Nm is None else np.asarray(drive_torque_Nm)
    offset = np.asarray(components.get("offset", 0.0))
    fig, (ax_loop, ax_parts) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    ax_loop.plot(measured_tau, _arcmin(run.angle_rad - offset), ".", ms=1.5, color="0.6", label="measured")
    ax_loop.plot(tau, _arcmin(components["total"] - offset), "-", lw=1.0, color="k", label="model (MAP)")
    ax_loop.set_xlabel("torque (N·m)")
    ax_loop.set_ylabel("twist (arcmin, per-run offset removed)")
    ax_loop.legend(loc="upper left", fontsize=8)
    ax_loop.set_title("loop")
    for name, (color, label) in COMPONENT_STYLE.items():
        part = np.asarray(components.get(name, 0.0))
        if np.ndim(part) and np.max(np.abs(part)) > 0:
            ax_parts.plot(tau, _arcmin(part), "-", lw=1.0, color=color, label=label)
    ax_parts.axhline(0, color="0.8", lw=0.5)
    ax_parts.set_xlabel("torque (N·m)")
    ax_parts.set_ylabel("component (arcmin)")
    ax_parts.legend(loc="upper left", fontsize=8)
    ax_parts.set_title("components (sum = model − offset)")
    fig.suptitle(f"{title or run.name} — {source}", fontsize=10)
    if path is not None:
        fig.savefig(path, dpi=130)
        plt.close(fig)
    return fig
