"""What a model parameter is: its name, its constraint (which sets the bijection the fit
uses), its SI unit and its meaning. Components declare these; nothing here holds values."""

from dataclasses import dataclass
from typing import Literal

Constraint = Literal["positive", "real", "unit_interval", "signed_unit"]  # signed_unit: (−1, 1)


@dataclass(frozen=True)
class Parameter:
    name: str
    constraint: Constraint
    unit: str  # SI unit of the value
    description: str
    size: int = 1  # > 1 for per-run or per-order vectors
    linear: bool = False  # enters the prediction linearly (offsets, harmonics, drift)
    # the model without the effect is this parameter's limit at zero (a lag, not a level whose
    # zero changes the shape): a fit extending the smaller model starts it near zero, there
    vanishes_at_zero: bool = False
