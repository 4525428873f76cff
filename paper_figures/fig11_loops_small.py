"""Fig. 11: the small reducer's loops at 0.02, 0.05 and 0.1 N·m/s, K_s of each (Table 4).

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig11_loops_small.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig11"))
