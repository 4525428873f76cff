"""Figures. Every figure says where its data came from (measured, with the source, or
SYNTHETIC); angles in arcmin, torque in N·m."""

import matplotlib

matplotlib.use("Agg")  # files only: no screen on benches and CI
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ._x64 import in_float64
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


# ----------------------------------------------------------------------------- fit figures

_MAX_POINTS = 3000  # points per curve in a figure
_BAND_DRAWS = 200  # posterior draws behind a band


@in_float64
def components_over_draws(problem, u_batch, idx_by_run: dict) -> dict:
    """Components of several runs for each draw, in one compiled pass: ``idx_by_run`` maps a
    run index to the sample indices wanted; returns run index → dict of (draws, n) arrays
    (with ``drive_torque`` for hysteresis runs)."""
    import jax.numpy as jnp

    runs = tuple(sorted(idx_by_run))
    idx = tuple(jnp.asarray(idx_by_run[r]) for r in runs)
    out = _components_at(problem, jnp.asarray(u_batch), runs, idx)
    return {r: {k: np.asarray(v) for k, v in d.items()} for r, d in zip(runs, out)}


def _components_at(problem, u_batch, runs: tuple, idx: tuple):
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    @eqx.filter_jit
    def over_draws(problem, u_batch, idx):
        def one(u):
            inputs = problem.corrected_inputs(u)
            comps = problem.model.components(problem.full_values(u), inputs)
            out = []
            for r, ix in zip(runs, idx):
                d = {k: v[ix] for k, v in comps[r].items() if jnp.ndim(v)}
                if hasattr(inputs[r], "torque_Nm") and jnp.ndim(inputs[r].torque_Nm):
                    d["drive_torque"] = inputs[r].torque_Nm[ix]
                out.append(d)
            return out

        return jax.lax.map(one, u_batch)

    return over_draws(problem, u_batch, idx)


@in_float64
def component_draws(problem, u_batch, run_index: int, idx):
    """Components of one run at sample indices ``idx`` for each draw (dict of (draws, n))."""
    return components_over_draws(problem, u_batch, {run_index: idx})[run_index]


def band(ax, x, draws, color, label=None, alpha=0.25, lw=0.8, ls="-"):
    """Median line and central 95 % band of ``draws`` (draws, points) along ``x``."""
    lo, mid, hi = np.percentile(np.asarray(draws), [2.5, 50, 97.5], axis=0)
    ax.fill_between(x, lo, hi, color=color, alpha=alpha, lw=0)
    ax.plot(x, mid, ls, color=color, lw=lw, label=label)


@in_float64
def write_fit_figures(fit, folder) -> list:
    """Every figure of a fit (``report.CampaignFit``) into ``folder``; returns the paths."""
    from pathlib import Path

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    source = fit.campaign.notes or "source not stated"
    rng = np.random.default_rng(0)
    u = fit.draws_u[rng.choice(len(fit.draws_u), size=min(_BAND_DRAWS, len(fit.draws_u)), replace=False)]
    sigma, _ = fit.problem.noise_values(np.asarray(fit.map_result.u))
    paths = []
    te_runs = []
    for i, run in enumerate(fit.campaign.runs):
        n = len(run)
        idx = np.unique(np.linspace(0, n - 1, min(n, _MAX_POINTS)).astype(int))
        comps = component_draws(fit.problem, u, i, idx)
        offset = comps["offset"]
        total = comps["total"] - offset
        noise = rng.normal(0.0, float(sigma[i]), total.shape)
        if run.kind == "hysteresis":
            tau = np.median(comps["drive_torque"], axis=0)
            measured = np.asarray(run.angle_rad)[idx] - np.median(offset, axis=0)
            fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
            a1.plot(np.asarray(run.torque_Nm)[idx], _arcmin(measured), ".", ms=1.5, color="0.6", label="measured")
            a1.plot(tau, _arcmin(np.median(total, axis=0)), "-", color="k", lw=0.8, label="posterior median")
            a1.set_xlabel("torque (N·m)")
            a1.set_ylabel("twist (arcmin, offset removed)")
            a1.legend(fontsize=8)
            a1.set_title("loop")
            median = np.median(total, axis=0)
            t = np.asarray(run.time_s)[idx]
            spread = _arcmin(total + noise - median[None, :]) * 60
            lo, hi = np.percentile(spread, [2.5, 97.5], axis=0)
            a2.fill_between(t, lo, hi, color="C0", alpha=0.25, lw=0, label="posterior predictive, 95 %")
            a2.plot(t, _arcmin(measured - median) * 60, ".", ms=1.5, color="k", label="measured − posterior median")
            a2.axhline(0, color="0.5", lw=0.5)
            a2.set_xlabel("time (s)")
            a2.set_ylabel("residual (arcsec)")
            a2.legend(fontsize=8, loc="upper right")
            a2.set_title("residual with posterior-predictive band")
            fig.suptitle(f"{run.name} — {source}", fontsize=9)
            path = folder / f"loop-{_safe(run.name)}.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            paths.append(path)

            fig, ax = plt.subplots(figsize=(7, 4.4), constrained_layout=True)
            for name in ("elastic", "friction", "geometric", "creep"):
                if name in comps and np.max(np.abs(comps[name])) > 0:
                    color, label = COMPONENT_STYLE[name]
                    # plot along the last full loop only (steps 2–5) so bands are readable
                    band(ax, tau, _arcmin(comps[name]), color, label)
            ax.axhline(0, color="0.8", lw=0.5)
            ax.set_xlabel("torque (N·m)")
            ax.set_ylabel("component of the twist (arcmin)")
            ax.legend(fontsize=8)
            ax.set_title(f"components with 95 % bands — {run.name}\n{source}", fontsize=9)
            path = folder / f"components-{_safe(run.name)}.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            paths.append(path)
        else:
            te_runs.append((i, run, idx, total))
    if te_runs:
        fig, ax = plt.subplots(figsize=(8, 4.4), constrained_layout=True)
        for k, (i, run, idx, total) in enumerate(te_runs):
            phi = np.degrees(np.asarray(run.output_angle_rad)[idx]) % 360
            order = np.argsort(phi)
            te0 = float(np.median([np.median(np.asarray(fit.map_result.values["te_offset"]))]))
            ax.plot(phi[order], _arcmin(np.asarray(run.te_rad)[idx][order] - te0), ".", ms=1, color=f"C{k % 10}")
            lo, hi = np.percentile(_arcmin(total), [2.5, 97.5], axis=0)
            ax.fill_between(phi[order], lo[order], hi[order], color=f"C{k % 10}", alpha=0.3, lw=0, label=run.name)
        ax.set_xlabel("output angle (°)")
        ax.set_ylabel("TE − TE₀ (arcmin)")
        ax.legend(fontsize=7, ncol=2)
        ax.set_title(f"transmission error with 95 % model bands\n{source}", fontsize=9)
        path = folder / "te-vs-angle.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        paths.append(path)
        paths.append(_kd_vs_speed(fit, folder, source))
    paths.append(_pair_plot(fit, folder, source))
    if fit.sample_result is not None:
        paths.append(_trace_plot(fit, folder, source))
    return paths


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def _physics_draws(fit):
    from .fit._transform import forward

    out, i = {}, 0
    for p in fit.problem.physics:
        for j in range(p.size):
            key = p.name if p.size == 1 else f"{p.name}[{j}]"
            out[key] = np.asarray(forward(p.constraint, fit.draws_u[:, i]))
            i += 1
    return out


def _pair_plot(fit, folder, source):
    draws = {k: v for k, v in _physics_draws(fit).items() if not k.startswith("friction_start")}
    names = list(draws)[:8]
    k = len(names)
    fig, axes = plt.subplots(k, k, figsize=(1.6 * k + 1, 1.6 * k + 1), squeeze=False)
    sub = np.random.default_rng(1).choice(len(fit.draws_u), size=min(1500, len(fit.draws_u)), replace=False)
    for r, a in enumerate(names):
        for c, b in enumerate(names):
            ax = axes[r, c]
            if c > r:
                ax.axis("off")
            elif c == r:
                ax.hist(draws[a][sub], bins=30, color="C0")
            else:
                ax.plot(draws[b][sub], draws[a][sub], ".", ms=1, alpha=0.3, color="C0")
            ax.tick_params(labelsize=5)
            if r == k - 1:
                ax.set_xlabel(b, fontsize=6)
            if c == 0:
                ax.set_ylabel(a, fontsize=6)
    fig.suptitle(f"posterior pairs (SI units) — {source}", fontsize=8)
    path = folder / "pairs.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _trace_plot(fit, folder, source):
    chain = np.asarray(fit.sample_result.chain)  # (steps, walkers, dim)
    names = fit.problem.names(fit.run_names)
    k = min(fit.problem.n_model, 8)
    fig, axes = plt.subplots(k, 1, figsize=(8, 1.3 * k + 0.8), sharex=True, squeeze=False)
    for j in range(k):
        axes[j, 0].plot(chain[:, : min(16, chain.shape[1]), j], lw=0.4, alpha=0.6)
        axes[j, 0].set_ylabel(names[j], fontsize=6)
        axes[j, 0].tick_params(labelsize=6)
    axes[-1, 0].set_xlabel("step (after burn-in and thinning); unconstrained scale")
    fig.suptitle(f"emcee trace, 16 walkers — {source}", fontsize=8)
    path = folder / "trace.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _kd_vs_speed(fit, folder, source):
    fig, ax = plt.subplots(figsize=(6.5, 4.2), constrained_layout=True)
    groups = {}
    for spec, col in zip(fit.metric_specs, fit.metric_draws.T):
        if spec.name.startswith("kd_mean[") and spec.condition:
            key = (spec.condition["torque_Nm"], spec.condition["direction"])
            lo, hi = np.percentile(col, [2.5, 97.5])
            groups.setdefault(key, []).append((spec.condition["speed_rpm"], np.median(col), lo, hi))
    for n, ((torque, direction), pts) in enumerate(sorted(groups.items())):
        pts.sort()
        v, med, lo, hi = (np.array(x) for x in zip(*pts))
        ax.errorbar(v, med, yerr=[med - lo, hi - med], fmt="o-", ms=3, capsize=3, color=f"C{n % 10}",
                    label=f"{torque:g} N·m, {direction}")
    ax.set_xlabel("output speed (rpm)")
    ax.set_ylabel("K_d at 180° (N·m/arcmin)")
    ax.legend(fontsize=8)
    ax.set_title(f"dynamic stiffness, 95 % intervals\n{source}", fontsize=9)
    path = folder / "kd-vs-speed.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
