"""An absolute encoder's wrap: an angle read modulo a full turn jumps by one turn between two
samples when the output crosses its zero (359.9° → 0.1°, 0.999 rev → 0.001 rev).

A hysteresis run twists a few degrees, so a step of about a full turn between two samples is
the encoder's wrap, not the reducer's motion: the run is unwrapped on reading, with a note. Read
as it is, the wrap reads as a twist of a whole turn, and the run stops on the angle's sign or
gets a loop a turn tall.
"""

import math

import numpy as np

TURN_RAD = 2.0 * math.pi
#: a step within this share of a full turn of ±1 turn is a wrap
WRAP_TOLERANCE = 0.1


def unwrap_full_turns(angle_rad) -> tuple[np.ndarray, int]:
    """(the angle with each step of 1 ± :data:`WRAP_TOLERANCE` turns taken out, the number of
    such steps)."""
    angle = np.asarray(angle_rad, float)
    step = np.diff(angle)
    turns = np.round(step / TURN_RAD)
    wraps = (turns != 0) & (np.abs(step - turns * TURN_RAD) < WRAP_TOLERANCE * TURN_RAD)
    if not wraps.any():
        return angle, 0
    correction = np.concatenate([[0.0], np.cumsum(np.where(wraps, turns, 0.0))]) * TURN_RAD
    return angle - correction, int(wraps.sum())
