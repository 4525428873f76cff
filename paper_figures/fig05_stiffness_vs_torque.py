"""Fig. 5: K_d(180°) versus torque at the grid's lowest speed: data, H with band, and the physics model's 95 % band (both reducers).

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig05_stiffness_vs_torque.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig05"))
