"""Fig. 6: K_d(180°) over torque × speed, the H surface with the grid's data points.

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig06_stiffness_surface.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig06"))
