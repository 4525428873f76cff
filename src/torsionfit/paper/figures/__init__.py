"""The paper's figures, one function per figure: ``make(repro, out_dir) -> [png, pdf]``."""

from ._decomposition import fig02_decomposition
from ._envelope import fig19_envelope
from ._hysteresis import fig01_protocol, fig11_loops_small, fig12_loops_large
from ._operating import (
    fig05_stiffness_vs_torque,
    fig06_stiffness_surface,
    fig15_kd_small,
    fig16_kt_small,
    fig17_kd_large,
    fig18_kt_large,
)
from ._te import fig13_te_small, fig14_te_large
from ._unification import fig04_te_on_loop

#: every figure by its key (the file stem's prefix), in the paper's order
FIGURES = {
    "fig01": fig01_protocol,
    "fig02": fig02_decomposition,
    "fig04": fig04_te_on_loop,
    "fig05": fig05_stiffness_vs_torque,
    "fig06": fig06_stiffness_surface,
    "fig11": fig11_loops_small,
    "fig12": fig12_loops_large,
    "fig13": fig13_te_small,
    "fig14": fig14_te_large,
    "fig15": fig15_kd_small,
    "fig16": fig16_kt_small,
    "fig17": fig17_kd_large,
    "fig18": fig18_kt_large,
    "fig19": fig19_envelope,
}

__all__ = ["FIGURES"]
