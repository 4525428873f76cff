"""Fig. 19: P1, P2 and the K_req plane; P(K_d,worn ≥ K_req) with the p_accept contours of both units.

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig19_envelope.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig19"))
