"""Figures. Every figure says where its data came from (measured, with the source, or
SYNTHETIC); angles in arcmin, torque in N·m."""

# no matplotlib.use(): importing must not switch the user's backend (a notebook keeps its inline
# figures); without a screen matplotlib picks Agg itself, and the figures here are saved to files
import matplotlib.pyplot as plt
import numpy as np

from ._x64 import in_float64
from .units import ANGLE_UNITS, SPEED_UNITS, STIFFNESS_UNITS, from_si  # noqa: E402

#: a parameter's SI unit → (the unit figures show it in, SI value of one shown unit)
SHOWN_UNITS = {
    "N·m/rad": ("N·m/arcmin", STIFFNESS_UNITS["Nm/arcmin"]),
    "rad": ("arcmin", ANGLE_UNITS["arcmin"]),
    "rad/s": ("arcsec/s", ANGLE_UNITS["arcsec"]),
    "N·m·s/rad": ("N·m/rpm", 1.0 / SPEED_UNITS["rpm"]),
    "s/rad": ("1/rpm", 1.0 / SPEED_UNITS["rpm"]),
    "s²/rad²": ("1/rpm²", 1.0 / SPEED_UNITS["rpm"] ** 2),
}
#: characters of a figure title's source line before it is wrapped
_TITLE_WIDTH = 100

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


def shown_unit(si_unit: str) -> tuple[str, float]:
    """(unit a figure shows, SI value of one such unit) for a parameter in ``si_unit``."""
    return SHOWN_UNITS.get(si_unit, (si_unit, 1.0))


def axis_label(name: str, si_unit: str) -> str:
    """``name (unit)`` in the shown unit; dimensionless parameters get no unit."""
    unit = shown_unit(si_unit)[0]
    return name if unit in ("1", "") else f"{name} ({unit})"


def _wrap(text: str, width: int = _TITLE_WIDTH) -> str:
    """``text`` broken into lines of at most ``width`` characters (long source lines)."""
    import textwrap

    return "\n".join(textwrap.wrap(text, width)) or text


def plot_loop_components(run, components: dict, *, source: str, drive_torque_Nm=None, path=None,
                         title: str | None = None, draws: dict | None = None, draws_label: str = "95 %"):
    """Measured hysteresis loop with the model's total, and the model's components versus
    the torque driving the model (``drive_torque_Nm``: the denoised, latent-corrected torque;
    default the measured one). ``components`` are the model's per-sample arrays (rad), e.g.
    ``MapResult.components()[i]``; ``source`` names where the data came from. ``draws``: the
    same components for parameter draws (name → (draws, samples) arrays in rad, e.g.
    :func:`component_draws` of Laplace draws around the MAP) add central 95 % bands, named in
    the legend by ``draws_label``."""
    measured_tau = np.asarray(run.torque_Nm)
    tau = measured_tau if drive_torque_Nm is None else np.asarray(drive_torque_Nm)
    offset = np.asarray(components.get("offset", 0.0))
    fig, (ax_loop, ax_parts) = plt.subplots(1, 2, figsize=(11, 4.6), constrained_layout=True)
    ax_loop.plot(measured_tau, _arcmin(run.angle_rad - offset), ".", ms=1.5, color="0.6", label="measured")
    if draws is not None:
        model = _arcmin(draws["total"] - draws.get("offset", 0.0))
        lo, hi = np.percentile(model, [2.5, 97.5], axis=0)
        # a well-determined fit's band is thinner than the line: its width says so
        band(ax_loop, tau, model, "k", f"model, {draws_label} (at most {np.max(hi - lo):.2g} arcmin wide)",
             alpha=0.3, lw=0.0)
    ax_loop.plot(tau, _arcmin(components["total"] - offset), "-", lw=0.8, color="k", label="model (MAP)")
    ax_loop.set_xlabel("torque (N·m)")
    ax_loop.set_ylabel("twist (arcmin, per-run offset removed)")
    ax_loop.legend(loc="upper left", fontsize=8)
    ax_loop.set_title("loop")
    for name, (color, label) in COMPONENT_STYLE.items():
        part = np.asarray(components.get(name, 0.0))
        if np.ndim(part) and np.max(np.abs(part)) > 0:
            if draws is not None and name in draws:
                band(ax_parts, tau, _arcmin(draws[name]), color, lw=0.0)
            ax_parts.plot(tau, _arcmin(part), "-", lw=1.0, color=color, label=label)
    ax_parts.axhline(0, color="0.8", lw=0.5)
    ax_parts.set_xlabel("torque (N·m)")
    ax_parts.set_ylabel("component (arcmin)")
    ax_parts.legend(loc="upper left", fontsize=8)
    shaded = f"; shaded: {draws_label}" if draws is not None else ""
    ax_parts.set_title(_wrap(f"components at the MAP (sum = model − offset){shaded}", 60), fontsize=9)
    fig.suptitle(_wrap(f"{title or run.name} — {source}"), fontsize=9)
    if path is not None:
        fig.savefig(path, dpi=130)
        plt.close(fig)
    return fig


# ----------------------------------------------------------------------------- fit figures

_MAX_POINTS = 3000  # points per curve in a figure
_BAND_DRAWS = 200  # posterior draws behind a band


@in_float64
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
    ax.fill_between(x, lo, hi, color=color, alpha=alpha, lw=0, label=label if not lw else None)
    if lw:  # lw=0: the band alone (a line is drawn by the caller)
        ax.plot(x, mid, ls, color=color, lw=lw, label=label)


@in_float64
@in_float64
def predictive_sd(problem, u_batch, run_index: int, idx) -> np.ndarray:
    """(draws, points) standard deviation of one new observation of run ``run_index`` at its
    samples ``idx``, for each draw of u: the run's noise level (with its noise shape) and, for
    an AR(1) run, the stationary sd σ/√(1−ρ²) — what a posterior-predictive band must add to
    the model's spread, or most data fall outside it."""
    out = []
    for u in np.asarray(u_batch):
        sigma = np.asarray(problem.sample_sigma(u)[run_index], float)
        rho = float(np.asarray(problem.noise_values(u)[1])[run_index])
        sd = sigma[idx] if sigma.ndim else np.full(len(idx), float(sigma))
        out.append(sd / np.sqrt(max(1.0 - rho**2, 1e-12)))
    return np.stack(out)


def predictive_draws(problem, u_batch, run_index: int, idx, model_draws, rng) -> np.ndarray:
    """Posterior-predictive draws (rad) of run ``run_index`` at samples ``idx``: each draw's
    model (``model_draws``, (draws, points)) plus a new observation's noise (``rng``)."""
    sd = predictive_sd(problem, u_batch, run_index, idx)
    return np.asarray(model_draws) + rng.normal(size=sd.shape) * sd


def write_fit_figures(fit, folder) -> list:
    """Every figure of a fit (``report.CampaignFit``) into ``folder``; returns the paths."""
    from pathlib import Path

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    source = fit.campaign.notes or "source not stated"
    rng = np.random.default_rng(0)
    u = fit.draws_u[rng.choice(len(fit.draws_u), size=min(_BAND_DRAWS, len(fit.draws_u)), replace=False)]
    paths = []
    te_runs = []
    for i, run in enumerate(fit.campaign.runs):
        n = len(run)
        idx = np.unique(np.linspace(0, n - 1, min(n, _MAX_POINTS)).astype(int))
        comps = component_draws(fit.problem, u, i, idx)
        offset = comps["offset"]
        total = comps["total"] - offset
        predictive = predictive_draws(fit.problem, u, i, idx, total, rng)
        if run.kind == "hysteresis":
            tau = np.median(comps["drive_torque"], axis=0)
            measured = np.asarray(run.angle_rad)[idx] - np.median(offset, axis=0)
            fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.6), constrained_layout=True)
            a1.plot(np.asarray(run.torque_Nm)[idx], _arcmin(measured), ".", ms=1.5, color="0.6", label="measured")
            a1.plot(tau, _arcmin(np.median(total, axis=0)), "-", color="k", lw=0.8, label="posterior median")
            a1.set_xlabel("torque (N·m)")
            a1.set_ylabel("twist (arcmin, offset removed)")
            a1.legend(fontsize=8)
            a1.set_title("loop")
            median = np.median(total, axis=0)
            t = np.asarray(run.time_s)[idx]
            lo, hi = np.percentile(_arcmin(predictive - median[None, :]) * 60, [2.5, 97.5], axis=0)
            a2.fill_between(t, lo, hi, color="C0", alpha=0.25, lw=0, label="posterior predictive, 95 %")
            a2.plot(t, _arcmin(measured - median) * 60, ".", ms=1.5, color="k", label="measured − posterior median")
            a2.axhline(0, color="0.5", lw=0.5)
            a2.set_xlabel("time (s)")
            a2.set_ylabel("residual (arcsec)")
            a2.legend(fontsize=8, loc="upper right")
            a2.set_title("residual with posterior-predictive band")
            fig.suptitle(_wrap(f"{run.name} — {source}"), fontsize=9)
            path = folder / f"loop-{_safe(run.name)}.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            paths.append(path)

            fig, ax = plt.subplots(figsize=(7, 4.6), constrained_layout=True)
            for name in ("elastic", "friction", "geometric", "creep"):
                if name in comps and np.max(np.abs(comps[name])) > 0:
                    color, label = COMPONENT_STYLE[name]
                    band(ax, tau, _arcmin(comps[name]), color, label)
            ax.axhline(0, color="0.8", lw=0.5)
            ax.set_xlabel("torque (N·m)")
            ax.set_ylabel("component of the twist (arcmin)")
            ax.legend(fontsize=8)
            ax.set_title(_wrap(f"components with 95 % posterior bands — {run.name} — {source}", 80), fontsize=9)
            path = folder / f"components-{_safe(run.name)}.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            paths.append(path)
        else:
            measured = np.asarray(run.te_rad)[idx] - np.median(offset, axis=0)
            te_runs.append((run, idx, measured, predictive))
    if te_runs:
        paths.append(_save(te_figure(te_runs, source), folder / "te-vs-angle.png", 120))
        paths.append(_save(kd_figure(fit, source), folder / "kd-vs-speed.png", 120))
    paths.append(_save(pairs_figure(fit, source), folder / "pairs.png", 110))
    # a trace is of Markov chains: Laplace draws are independent, there is nothing to trace
    if fit.sample_result is not None and getattr(fit.sample_result, "sampler", "emcee") != "laplace":
        paths.append(_save(trace_figure(fit, source), folder / "trace.png", 110))
    return paths


def _save(fig, path, dpi: int):
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def te_figure(te_runs, source):
    """TE against output angle per run, each with its 95 % posterior-predictive band;
    ``te_runs``: (run, sample indices, measured TE − zero, predictive draws) per run (rad)."""
    fig, ax = plt.subplots(figsize=(8, 4.6), constrained_layout=True)
    for k, (run, idx, measured, predictive) in enumerate(te_runs):
        phi = np.degrees(np.asarray(run.output_angle_rad)[idx]) % 360
        order = np.argsort(phi, kind="stable")
        color = f"C{k % 10}"
        ax.plot(phi[order], _arcmin(measured[order]), ".", ms=1, color=color)
        lo, hi = np.percentile(_arcmin(predictive), [2.5, 97.5], axis=0)
        ax.fill_between(phi[order], lo[order], hi[order], color=color, alpha=0.25, lw=0, label=run.name)
    ax.set_xlabel("output angle (°)")
    ax.set_xticks(np.arange(0, 361, 45))
    ax.set_ylabel("TE − TE₀ (arcmin)")
    ax.legend(fontsize=7, ncol=2, title="dots: measured; shaded: posterior predictive, 95 %", title_fontsize=7)
    ax.set_title(_wrap(f"transmission error — {source}", 80), fontsize=9)
    return fig


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def _physics_draws(fit, chain=None):
    """Physical parameters in the units figures show: name → (values, axis label). ``chain``:
    an array of u with the entries last (default the fit's draws); values keep its shape."""
    from .fit._transform import forward

    u = fit.draws_u if chain is None else chain
    out, i = {}, 0
    for p in fit.problem.physics:
        unit, one = shown_unit(p.unit)
        for j in range(p.size):
            key = p.name if p.size == 1 else f"{p.name}[{j}]"
            out[key] = (np.asarray(forward(p.constraint, u[..., i])) / one, axis_label(key, p.unit))
            i += 1
    return out


def pairs_figure(fit, source: str):
    """Pairs of the physical parameters' posterior draws, in the units of :data:`SHOWN_UNITS`."""
    from matplotlib.ticker import MaxNLocator

    from .model import RUN_START_STATES

    draws = {k: v for k, v in _physics_draws(fit).items() if not k.startswith(RUN_START_STATES)}
    names = list(draws)[:8]
    k = len(names)
    size = 1.9 * k + 1.2
    fig, axes = plt.subplots(k, k, figsize=(size, size), squeeze=False, constrained_layout=True)
    sub = np.random.default_rng(1).choice(len(fit.draws_u), size=min(1500, len(fit.draws_u)), replace=False)
    lims = {}
    for name in names:  # one range per parameter: a column's panels share the bottom row's ticks
        lo, hi = np.min(draws[name][0][sub]), np.max(draws[name][0][sub])
        pad = 0.04 * (hi - lo) or 0.5 * abs(hi) or 1.0
        lims[name] = (lo - pad, hi + pad)
    for r, a in enumerate(names):
        for c, b in enumerate(names):
            ax = axes[r, c]
            if c > r:
                ax.axis("off")
                continue
            if c == r:
                ax.hist(draws[a][0][sub], bins=30, range=lims[a], color="C0")
                ax.set_yticks([])
            else:
                ax.plot(draws[b][0][sub], draws[a][0][sub], ".", ms=1, alpha=0.3, color="C0")
                ax.set_ylim(lims[a])
                ax.yaxis.set_major_locator(MaxNLocator(3))
            ax.set_xlim(lims[b])
            ax.xaxis.set_major_locator(MaxNLocator(3))
            ax.tick_params(labelsize=7)
            if r < k - 1:
                ax.tick_params(labelbottom=False)
            else:
                ax.set_xlabel(draws[b][1], fontsize=8)
            if c > 0:
                ax.tick_params(labelleft=False)
            elif r > 0:
                ax.set_ylabel(draws[a][1], fontsize=8)
    more = f"; first {k} of {len(draws)} parameters" if len(draws) > k else ""
    fig.suptitle(_wrap(f"posterior pairs ({len(sub)} draws{more}) — {source}", 25 * k), fontsize=9)
    return fig


#: walkers or chains drawn in a trace plot
_TRACE_LINES = 16


def trace_figure(fit, source: str):
    """Trace of the physical parameters per walker (emcee) or chain (NUTS), in shown units;
    the title gives the true walker or chain count and how many are drawn."""
    result = fit.sample_result
    chain = np.asarray(result.chain)  # (draws, walkers or chains, dim)
    params = _physics_draws(fit, chain)
    names = list(params)[:8]
    k = len(names)
    n_lines = chain.shape[1]
    shown = min(_TRACE_LINES, n_lines)
    fig, axes = plt.subplots(k, 1, figsize=(8, 1.3 * k + 1.0), sharex=True, squeeze=False,
                             constrained_layout=True)
    for j, name in enumerate(names):
        values, label = params[name]
        axes[j, 0].plot(values[:, :shown], lw=0.4, alpha=0.6)
        axes[j, 0].set_ylabel(label.replace(" (", "\n("), fontsize=7)
        axes[j, 0].tick_params(labelsize=7)
    sampler = getattr(result, "sampler", "sampler")
    what = "chains" if sampler == "nuts" else "walkers"
    drawn = f"all {n_lines} {what}" if shown == n_lines else f"{shown} of {n_lines} {what}"
    axes[-1, 0].set_xlabel(f"draw (after {'warm-up' if sampler == 'nuts' else 'burn-in and thinning'})")
    more = f"; first {k} of {len(params)} parameters" if len(params) > k else ""
    fig.suptitle(_wrap(f"{sampler} trace, {drawn}, {chain.shape[0]} draws each{more} — {source}"), fontsize=8)
    return fig


def kd_figure(fit, source: str):
    """K_d at 180° against output speed per (torque, direction); a condition measured at one
    speed is a point with its interval, not a line."""
    fig, ax = plt.subplots(figsize=(6.5, 4.4), constrained_layout=True)
    groups = {}
    for spec, col in zip(fit.metric_specs, fit.metric_draws.T):
        if spec.name.startswith("kd_mean[") and spec.condition:
            key = (spec.condition["torque_Nm"], spec.condition["direction"])
            lo, hi = np.percentile(col, [2.5, 97.5])
            groups.setdefault(key, []).append((spec.condition["speed_rpm"], np.median(col), lo, hi))
    speeds = set()
    for n, ((torque, direction), pts) in enumerate(sorted(groups.items())):
        pts.sort()
        v, med, lo, hi = (np.array(x) for x in zip(*pts))
        speeds.update(v.tolist())
        ax.errorbar(v, med, yerr=[med - lo, hi - med], fmt="o-" if len(v) > 1 else "o", ms=4, capsize=3,
                    color=f"C{n % 10}", label=f"{torque:g} N·m, {direction}")
    ax.set_xlim(0.0, 1.15 * max(speeds, default=1.0))  # speed from standstill: a trend reads true
    ax.set_xlabel("output speed (rpm)")
    ax.set_ylabel("K_d at 180° (N·m/arcmin)")
    if groups:
        ax.legend(fontsize=8)
    note = "; one speed per condition: no speed trend" if all(len(p) == 1 for p in groups.values()) else ""
    ax.set_title(_wrap(f"dynamic stiffness, medians with 95 % intervals{note} — {source}", 70), fontsize=9)
    return fig
