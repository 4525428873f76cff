"""torsionfit: torsional stiffness of gear reducers from test-bench data, with uncertainty."""

import jax as _jax

# Fitting needs double precision (angles of arcseconds on top of offsets of degrees).
_jax.config.update("jax_enable_x64", True)

from . import io as io, units as units  # noqa: E402
from ._errors import InputError as InputError  # noqa: E402

__version__ = "0.1.0"
