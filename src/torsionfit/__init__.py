"""torsionfit: torsional stiffness of gear reducers from test-bench data, with uncertainty.

Importing torsionfit changes no JAX setting: its entry points compute in float64 under JAX's
scoped, thread-local switch (``torsionfit.float64``), and the user's session keeps its own
``jax_enable_x64``. To call building blocks (model components, ``FitProblem`` methods) directly
in float64, use ``with torsionfit.float64(): ...``.
"""

from . import io as io, units as units
from ._errors import InputError as InputError
from ._x64 import float64 as float64

__version__ = "0.1.0"
