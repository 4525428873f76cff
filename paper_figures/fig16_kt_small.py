"""Fig. 16: the small reducer's K_t (revolution mean) versus torque for each grid speed.

SYNTHETIC data calibrated to the published tables. ``python paper_figures/fig16_kt_small.py -o DIR [--quick]``
writes this figure (PNG and PDF); ``torsionfit paper -o DIR`` makes every figure, tables.json and the
comparison page at once."""

import sys

from torsionfit.paper import figure_script

if __name__ == "__main__":
    sys.exit(figure_script("fig16"))
