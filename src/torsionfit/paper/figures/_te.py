"""Figs. 13 and 14: transmission error over one output revolution at rated load and three
speeds (Table 5), the measured runs with the fitted model's 95 % band, K_d at 180° marked."""

import numpy as np

from ...units import from_si
from .._published import published
from .._tables import reproduced_value
from ._style import REDUCER_TITLE, band, figure, save

SPEED_COLORS = ("C0", "C1", "C3")


def _te(repro, out_dir, name: str, reducer: str, number: int):
    fit = repro.fit(name)
    campaign = repro.campaign(name)
    metrics = repro.data_metrics(name)
    fig, axes = figure(1, width=8.0)
    ax = axes[0][0]
    for color, p in zip(SPEED_COLORS, published("table6", reducer)):
        run = next(r for r in campaign.te_runs if r.name == p.run)
        phi = np.degrees(np.asarray(run.output_angle_rad)) % 360.0
        ax.plot(phi, from_si(np.asarray(run.te_rad), "angle", "arcmin"), ".", ms=1.5, color=color, rasterized=True)
        comps = repro.run_components(name)[p.run]
        fitted_phi = np.degrees(np.asarray(next(r for r in fit.campaign.te_runs if r.name == p.run).output_angle_rad))
        x = fitted_phi[comps["index"]] % 360.0
        order = np.argsort(x)
        got = reproduced_value(metrics, p)
        band(ax, x[order], from_si(comps["total"][:, order], "angle", "arcmin"), color,
             label=f"{p.speed_rpm:g} rpm: K_d(180°) {got:.5g} N·m/° (published {p.value_Nm_per_deg:g})")
    ax.axvline(180.0, color="k", lw=0.6, ls=":")
    ax.set_xlim(0, 360)
    ax.set_xlabel("output angle φ (°)")
    ax.set_ylabel("TE = θ_out − θ_in/R against the encoders' zero (arcmin)")
    ax.legend(fontsize=7, loc="best")
    ax.set_title(f"at T_r = {campaign.reducer.rated_torque_Nm:g} N·m, forward; dots: data, lines: model median "
                 f"and 95 % band ({fit.diagnostics['sampler']})", fontsize=8)
    return save(fig, out_dir, f"fig{number}_te_{reducer}",
                f"Fig. {number} — dynamic stiffness test results, {REDUCER_TITLE[name]}")


def fig13_te_small(repro, out_dir):
    """Fig. 13: the small reducer's TE at 1, 5 and 10 rpm (Tables 5, 6)."""
    return _te(repro, out_dir, "paper-small", "small", 13)


def fig14_te_large(repro, out_dir):
    """Fig. 14: the large reducer's TE at 1, 5 and 10 rpm (Tables 5, 6)."""
    return _te(repro, out_dir, "paper-large", "large", 14)
