"""Do the TE zeros leave the TE anything to say about the twist under load?

A TE run's level is its zero group's TE offset plus the twist under its load and direction
(lag-positive, d·(|τ| + T_f)/K + the gap's share). The model fits one offset per zero group, so
only differences between runs that share a zero carry the twist: loads apart in one direction
give the stiffness, the two directions at one load the friction and the gap. A bench that
re-zeroes its encoders before every test and runs each test at one load in one direction leaves
every group a single state: the offsets absorb the twist whole, the TE runs say nothing of the
stiffness, the friction or the lost motion, and the TE sign convention cannot be checked
(:mod:`~torsionfit.io._convention` compares runs of one zero). Without hysteresis runs the fit's
stiffness is then its prior, with intervals to match: the reader says so in one line. With
them the loops carry the twist and the TE runs their ripple (loops and one TE run is a common
layout): nothing is said.
"""

from ._campaign import HysteresisRun, TransmissionErrorRun
from ._plausibility import warn


def _state(run: TransmissionErrorRun) -> tuple:
    """What sets a run's twist: its load, direction, speed (viscous friction, a speed-dependent
    compliance) and temperature (a temperature-dependent compliance)."""
    return run.torque_Nm, run.direction, run.speed_rpm, run.nominal_temperature_C


def _shown(run: TransmissionErrorRun) -> str:
    return f"{run.torque_Nm:g} N·m {'forward' if run.direction > 0 else 'backward'}"


def check_te_zero_groups(runs, where: str) -> None:
    """Warn when every TE zero group holds runs at one load in one direction (and one speed and
    temperature; see the module text); nothing when a group holds two states or no TE run is
    given."""
    if any(isinstance(r, HysteresisRun) for r in runs):
        return  # the loops carry the twist; the TE runs give their ripple (a common layout)
    groups: dict = {}  # zero group → its runs
    for run in runs:
        if isinstance(run, TransmissionErrorRun):
            groups.setdefault(run.zero_group, []).append(run)
    if not groups or any(len({_state(r) for r in members}) > 1 for members in groups.values()):
        return
    shown = "; ".join(f"{'(shared)' if g is None else g}: {_shown(members[0])}" for g, members in list(groups.items())[:4])
    if len(groups) > 4:
        shown += f"; ... ({len(groups)} groups)"
    warn(f"{where}: every TE zero group holds runs at one load in one direction ({shown}): each group's TE "
         f"zero absorbs its twist under load, so the TE runs say nothing of the twist and te_convention goes "
         f"unchecked; with no hysteresis run the fit's stiffness, friction and lost motion are their priors. "
         f"Runs that share an encoder zero (a test's forward and backward revolutions, or its loads) need the "
         f"same zero_group")
