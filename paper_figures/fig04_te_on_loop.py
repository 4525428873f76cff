"""Fig. 4: near T_r, the slowest loop's loading branch, the TE(180°) at T_r of each speed, and the model's θ(T_r) at τ̇ → 0 and TE(180°) at v → 0 with 95 % intervals, for both reducers.

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig04_te_on_loop.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig04"))
