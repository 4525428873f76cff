"""Fig. 14: the large reducer's TE at 1, 5 and 10 rpm (Tables 5, 6).

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig14_te_large.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig14"))
