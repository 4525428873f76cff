"""Fig. 2: the measured loop and the posterior median; the parts along it with bands; the parts of the angle at T_r with their 95 % HDIs (large reducer).

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig02_decomposition.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig02"))
