"""Fig. 12: the large reducer's loops at 1, 2.5 and 5 N·m/s, K_s of each (Table 4).

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig12_loops_large.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig12"))
