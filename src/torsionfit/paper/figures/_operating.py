"""Stiffness under all operating conditions (paper §3.3, §4.4): K_d versus torque at one
speed (Fig. 5), over torque × speed (Fig. 6), at 180° for several speeds (Figs. 15, 17) and
the revolution mean K_t (Figs. 16, 18). Points: the grid's TE runs evaluated from the data
alone; lines and bands: the polynomial H of Eqs. (26)–(28) over its coefficients' posterior;
dashed: the physics model fitted to the bundled rated-load runs, predicting the grid."""

import numpy as np

from .._posterior import kd_draws
from .._reproduction import derived_seed
from ._style import REDUCER_TITLE, band, figure, per_deg, save

QUANTITY = {"kd": ("K_d = τ / TE(180°)", "kd_Nm_per_arcmin", "Eq. (27)"),
            "kt": ("K_t = τ / mean TE over a revolution", "kt_Nm_per_arcmin", "Eq. (28)")}
N_FINE = 60


def _h_draws(repro, name: str, quantity: str, torque_Nm, speed_rpm):
    """(draws, points) of H = τ / P(τ, v) in N·m/° over the polynomial's posterior."""
    poly = repro.polynomial(name, quantity)
    te = poly.predict_draws(torque_Nm, speed_rpm, repro.settings.band_draws,
                            derived_seed(repro.settings.seed, f"H {name} {quantity}"))
    return per_deg(np.asarray(torque_Nm)[None, :] / te)


def _fine_torque(grid):
    return np.linspace(grid.torque_Nm[0], grid.torque_Nm[-1], N_FINE)


def _versus_torque(ax, repro, name, quantity, speeds, physics: bool):
    grid = repro.grid(name)
    label, key, _ = QUANTITY[quantity]
    fine = _fine_torque(grid)
    data = per_deg(getattr(grid, key))
    for c, i in enumerate(speeds):
        v = grid.speed_rpm[i]
        color = f"C{c % 10}"
        ax.plot(grid.torque_Nm, data[i], "o", color=color, ms=4)
        band(ax, fine, _h_draws(repro, name, quantity, fine, np.full_like(fine, v)), color, label=f"{v:.3g} rpm")
        if physics:
            k = per_deg(kd_draws(repro.fit(name), fine, np.full_like(fine, v)))
            ax.plot(fine, np.median(k, axis=0), "--", color=color, lw=0.9)
    ax.set_xlabel("load torque τ (N·m)")
    ax.set_ylabel(f"{label} (N·m/°)")


def _poly_text(repro, name, quantity) -> str:
    p = repro.polynomial(name, quantity)
    return f"H: TE polynomial of degree {p.degrees[0]} in τ, {p.degrees[1]} in v (BIC), residual sd {p.sigma:.2g} arcmin"


def fig05_stiffness_vs_torque(repro, out_dir):
    """Fig. 5: K_d(180°) versus torque at the grid's lowest speed: data, H with band, and the
    physics model's 95 % band (both reducers)."""
    fig, axes = figure(2)
    for ax, name in zip(axes[0], ("paper-small", "paper-large")):
        grid = repro.grid(name)
        fine = _fine_torque(grid)
        v = grid.speed_rpm[0]
        ax.plot(grid.torque_Nm, per_deg(grid.kd_Nm_per_arcmin[0]), "ko", ms=4, label="grid TE runs, data alone")
        band(ax, fine, _h_draws(repro, name, "kd", fine, np.full_like(fine, v)), "C0", label="H (Eq. 26), 95 % band")
        band(ax, fine, per_deg(kd_draws(repro.fit(name), fine, np.full_like(fine, v))), "C1", ls="--",
             label="physics model fitted to the rated-load runs, 95 % band")
        ax.set_xlabel("load torque τ (N·m)")
        ax.set_ylabel("K_d = τ / TE(180°) (N·m/°)")
        ax.legend(fontsize=7, loc="lower right")
        ax.set_title(f"{REDUCER_TITLE[name]}, {v:.3g} rpm\n{_poly_text(repro, name, 'kd')}", fontsize=8)
    return save(fig, out_dir, "fig05_stiffness_vs_torque", "Fig. 5 — torsional stiffness curve: K_d versus torque at one speed")


def fig06_stiffness_surface(repro, out_dir):
    """Fig. 6: K_d(180°) over torque × speed, the H surface with the grid's data points."""
    fig, axes = figure(2, width=6.0, height=5.0, subplot_kw={"projection": "3d"})
    for ax, name in zip(axes[0], ("paper-small", "paper-large")):
        grid = repro.grid(name)
        t, v = np.meshgrid(_fine_torque(grid), np.linspace(grid.speed_rpm[0], grid.speed_rpm[-1], 30))
        poly = repro.polynomial(name, "kd")
        k = per_deg(t.ravel() / poly.predict(t.ravel(), v.ravel())).reshape(t.shape)
        ax.plot_surface(t, v, k, cmap="viridis", alpha=0.75, lw=0)
        gt, gv = grid.points()
        ax.scatter(gt, gv, per_deg(grid.kd_Nm_per_arcmin).ravel(), color="k", s=8)
        ax.set_xlabel("τ (N·m)", fontsize=8)
        ax.set_ylabel("v (rpm)", fontsize=8)
        ax.set_zlabel("K_d (N·m/°)", fontsize=8)
        ax.tick_params(labelsize=6)
        ax.set_title(f"{REDUCER_TITLE[name]}\nsurface: H (posterior mean); dots: grid TE runs", fontsize=8)
    return save(fig, out_dir, "fig06_stiffness_surface", "Fig. 6 — torsional stiffness evaluation model K_d(τ, v)")


def _speeds_figure(repro, out_dir, name, quantity, number, stem):
    grid = repro.grid(name)
    fig, axes = figure(1, width=7.5)
    ax = axes[0][0]
    physics = quantity == "kd"
    _versus_torque(ax, repro, name, quantity, range(len(grid.speed_rpm)), physics)
    ax.legend(fontsize=7, loc="lower right", title="output speed", title_fontsize=7)
    extra = "; dashed: physics model (median)" if physics else ""
    ax.set_title(f"{QUANTITY[quantity][2]}; dots: grid TE runs (data alone); lines: H with 95 % band{extra}\n"
                 f"{_poly_text(repro, name, quantity)}", fontsize=8)
    where = "at the 180° position" if quantity == "kd" else "revolution mean"
    return save(fig, out_dir, stem, f"Fig. {number} — {REDUCER_TITLE[name]}, {where}")


def fig15_kd_small(repro, out_dir):
    """Fig. 15: the small reducer's K_d at 180° versus torque for each grid speed."""
    return _speeds_figure(repro, out_dir, "paper-small", "kd", 15, "fig15_kd_small")


def fig16_kt_small(repro, out_dir):
    """Fig. 16: the small reducer's K_t (revolution mean) versus torque for each grid speed."""
    return _speeds_figure(repro, out_dir, "paper-small", "kt", 16, "fig16_kt_small")


def fig17_kd_large(repro, out_dir):
    """Fig. 17: the large reducer's K_d at 180° versus torque for each grid speed."""
    return _speeds_figure(repro, out_dir, "paper-large", "kd", 17, "fig17_kd_large")


def fig18_kt_large(repro, out_dir):
    """Fig. 18: the large reducer's K_t (revolution mean) versus torque for each grid speed."""
    return _speeds_figure(repro, out_dir, "paper-large", "kt", 18, "fig18_kt_large")
