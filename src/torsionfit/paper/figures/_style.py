"""What every paper figure shares: the SYNTHETIC label, units, saving as PNG and PDF."""

from pathlib import Path

import matplotlib.pyplot as plt  # the user's backend is left alone (no matplotlib.use on import)
import numpy as np

from ... import plots  # noqa: E402
from .._published import SYNTHETIC_LABEL  # noqa: E402

FOOTER = f"{SYNTHETIC_LABEL} (Cheng et al. 2023, Tables 4 and 6); not the paper's measurements — torsionfit paper"
REDUCER_TITLE = {"paper-small": "small reducer (T_r = 1 N·m)", "paper-large": "large reducer (T_r = 380 N·m)"}
ARCMIN_PER_DEG = 60.0


def figure(ncols: int = 1, nrows: int = 1, width: float = 6.0, height: float = 4.4, **kw):
    """A figure with room for the footer label."""
    fig, axes = plt.subplots(nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False, **kw)
    fig.subplots_adjust(bottom=0.18 if nrows == 1 else 0.1, top=0.82 if nrows == 1 else 0.9)
    return fig, axes


def save(fig, out_dir, stem: str, title: str) -> list[Path]:
    """Title, footer label, ``out_dir/stem.png`` and ``.pdf``; closes the figure."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig.suptitle(title, fontsize=10)
    fig.text(0.5, 0.01, FOOTER, ha="center", va="bottom", fontsize=7, color="0.3")
    paths = [out / f"{stem}.png", out / f"{stem}.pdf"]
    fig.savefig(paths[0], dpi=120)
    fig.savefig(paths[1], dpi=150)  # the rasterized dense scatter
    plt.close(fig)
    return paths


def band(ax, x, draws, color, label=None, alpha=0.25, lw=1.0, ls="-"):
    """``torsionfit.plots.band`` with the paper figures' line width."""
    plots.band(ax, x, draws, color, label, alpha, lw, ls)


def per_deg(k_Nm_per_arcmin):
    """N·m/arcmin → the paper's N·m/°."""
    return np.asarray(k_Nm_per_arcmin) * ARCMIN_PER_DEG
