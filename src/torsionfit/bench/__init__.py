"""The virtual test bench: reducers with known truth, measured by simulated sensors."""

from ._config import (
    EFFECTS as EFFECTS,
    Bench as Bench,
    HysteresisSpec as HysteresisSpec,
    Noise as Noise,
    TEExport as TEExport,
    TESpec as TESpec,
    load_bench as load_bench,
)
from ._export import write_te_export as write_te_export
from ._simulate import (
    Simulation as Simulation,
    five_step_protocol as five_step_protocol,
    simulate as simulate,
    truth_model as truth_model,
)
