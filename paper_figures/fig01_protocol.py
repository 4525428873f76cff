"""Fig. 1: torque over time with the five steps, and the loop they draw (large reducer, slowest loading rate), with the secant K_s = T_r / θ_r.

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig01_protocol.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig01"))
