"""What the forward model is driven by, per run, as JAX arrays (SI units)."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np


class HysteresisInput(eqx.Module):
    """Input locked, output loaded: the drive torque sequence and its time stamps.

    ``torque_Nm`` should be the *denoised* measured torque: raw sensor noise fakes tiny
    reversals and makes the friction state chatter.
    """

    time_s: jnp.ndarray
    torque_Nm: jnp.ndarray
    #: the run's temperature above the campaign's reference (K; 0: at the reference)
    temperature_delta_K: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0.0))
    #: 1 on the samples of the run's smallest cycles (the play ramps), 0 elsewhere
    #: (``metrics.small_cycle_rows``); what a torque zero of their own applies to
    small_cycle: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0.0))


class TEInput(eqx.Module):
    """Rotating under constant load: output angles, nominal load, speed and direction."""

    output_angle_rad: jnp.ndarray
    time_s: jnp.ndarray
    torque_Nm: jnp.ndarray  # scalar, nominal load ≥ 0
    speed_rad_s: jnp.ndarray  # scalar, output speed ≥ 0
    direction: jnp.ndarray  # scalar, +1 forward, −1 backward
    zero_group: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0))  # index into te_offset
    #: the run's temperature above the campaign's reference (K; 0: at the reference)
    temperature_delta_K: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0.0))


def hysteresis_input(time_s, torque_Nm, temperature_delta_K: float = 0.0, small_cycle=None) -> HysteresisInput:
    """``small_cycle``: the samples of the smallest cycles (bool or 0/1 per sample); None: none."""
    small = jnp.asarray(0.0) if small_cycle is None else jnp.asarray(np.asarray(small_cycle, float))
    return HysteresisInput(jnp.asarray(time_s, float), jnp.asarray(torque_Nm, float), jnp.asarray(float(temperature_delta_K)), small)


def te_input(output_angle_rad, torque_Nm, speed_rpm, direction, time_s=None, zero_group: int = 0,
             temperature_delta_K: float = 0.0) -> TEInput:
    phi = np.asarray(output_angle_rad, float)
    if time_s is None:  # constant speed: time follows from the angle travelled (either direction)
        speed = max(speed_rpm * 2 * np.pi / 60, 1e-12)
        # an output angle logged modulo a turn jumps back by one at each wrap: not a turn travelled
        time_s = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(np.unwrap(phi))))]) / speed
    return TEInput(
        jnp.asarray(phi),
        jnp.asarray(time_s, float),
        jnp.asarray(float(torque_Nm)),
        jnp.asarray(speed_rpm * 2 * np.pi / 60.0),
        jnp.asarray(float(direction)),
        jnp.asarray(int(zero_group)),
        jnp.asarray(float(temperature_delta_K)),
    )
