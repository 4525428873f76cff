"""One model for a whole campaign: shared physics, per-run offsets (DESIGN §1.1–1.3).

Components, every one returned separately and summing to the total:

- ``elastic``   C(τ): the spring's twist at the applied torque (single-valued in τ);
- ``friction``  [C + θ_g](τ_m) − [C + θ_g](τ): what friction changes (the hysteresis);
- ``geometric`` θ_g(τ): lost motion of the mesh at the applied torque;
- ``creep``     θ_c: the rate-dependent part (off in the base model): a creep element and what a
  damped gap crossing changes;
- ``kinematic`` θ_kin(φ): kinematic error (TE runs only);
- ``drift``     slow per-run drift (off in the base model);
- ``offset``    θ_0 per hysteresis run, TE_0 shared by all TE runs.

This split is the paper's Eq. (3): θ_out = θ_e(τ) + θ_f(τ, τ̇) + θ_g(τ) (+ θ_in/R).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._backlash import AbstractBacklash, SmoothBacklash
from ._compliance import AbstractCompliance, LinearCompliance
from ._creep import Creep
from ._drift import drift_parameters, run_drift
from ._friction import AbstractFriction, DahlFriction
from ._gap_lag import GapLag
from ._inputs import HysteresisInput, TEInput
from ._kinematic import KinematicHarmonics
from ._parameter import Parameter
from ._recurrence import ScanMethod
from ._series import SeriesCompliance
from ._speed import SpeedDependence
from ._temperature import TemperatureDependence

COMPONENTS = ("elastic", "friction", "geometric", "creep", "kinematic", "drift", "offset")

#: parameters holding a hysteresis run's state at its first sample (a run may start anywhere in
#: the unit's history): the friction state z0 and, with a hysteretic gap, the gap state g0
RUN_START_STATES = ("friction_start", "gap_start")


class CampaignModel(eqx.Module):
    """Forward model of a campaign with ``run_kinds`` (in campaign order).

    The base model is linear compliance + Dahl friction + smooth backlash + offsets; every
    other part is ``None``/``False`` until switched on (by hand or by the effects catalog).
    """

    run_kinds: tuple[str, ...] = eqx.field(static=True)
    compliance: AbstractCompliance = LinearCompliance()
    friction: AbstractFriction = DahlFriction()
    backlash: AbstractBacklash = SmoothBacklash()
    creep: Creep | None = None
    #: the gap crossing trails the mesh torque through a first-order lag (hysteresis runs)
    gap_lag: GapLag | None = None
    kinematic: KinematicHarmonics | None = None
    speed: SpeedDependence | None = None
    #: compliance and friction level changing with the run's temperature (inputs carry ΔT)
    temperature: TemperatureDependence | None = None
    #: a share of the compliance ahead of the friction (it sees the applied torque)
    series: SeriesCompliance | None = None
    drift: bool = eqx.field(static=True, default=False)
    drift_shape: str = eqx.field(static=True, default="linear")  # _drift.SHAPES
    torque_offset: bool = eqx.field(static=True, default=False)
    #: the torque reading's zero on the smallest cycles (the play ramps) differs from the
    #: larger ones' (a torque estimated from motor current): one offset for those samples
    play_torque_offset: bool = eqx.field(static=True, default=False)
    #: friction state at the start of each hysteresis run as a parameter (a run may start
    #: anywhere in the unit's history); False: the friction module's fixed initial state
    free_friction_start: bool = eqx.field(static=True, default=False)
    scan: ScanMethod = eqx.field(static=True, default="auto")
    #: TE zeros: one ``te_offset`` per zero group (benches that re-zero before each test);
    #: a TE run's group is ``TEInput.zero_group``
    te_zero_groups: int = eqx.field(static=True, default=1)

    def __check_init__(self):
        bad = [k for k in self.run_kinds if k not in ("hysteresis", "transmission_error")]
        if bad:
            raise ValueError(f"unknown run kind {bad[0]!r}")

    @property
    def n_hysteresis(self) -> int:
        return sum(k == "hysteresis" for k in self.run_kinds)

    @property
    def n_te(self) -> int:
        return sum(k == "transmission_error" for k in self.run_kinds)

    def parameters(self) -> tuple[Parameter, ...]:
        """Every parameter of this model, physics first, then the linear per-run ones."""
        out = self.compliance.parameters() + self.friction.parameters() + self.backlash.parameters()
        if self.creep is not None:
            out += self.creep.parameters()
        if self.gap_lag is not None and self.n_hysteresis:
            out += self.gap_lag.parameters()
        if self.speed is not None and self.n_te:
            out += self.speed.parameters()
        if self.temperature is not None:
            out += self.temperature.parameters()
        if self.series is not None:
            out += self.series.parameters()
        if self.torque_offset:
            out += (Parameter("torque_offset", "real", "N·m", "torque-sensor offset"),)
        if self.play_torque_offset and self.n_hysteresis:
            out += (Parameter("play_torque_offset", "real", "N·m",
                              "torque-sensor offset on the smallest cycles (play ramps), beyond the larger ones'"),)
        if self.free_friction_start and self.n_hysteresis:
            out += (Parameter("friction_start", "signed_unit", "1", "friction state z at the start of each hysteresis run", self.n_hysteresis),)
            if self.backlash.hysteretic:
                out += (Parameter("gap_start", "signed_unit", "1", "gap state g at the start of each hysteresis run", self.n_hysteresis),)
        if self.n_hysteresis:
            out += (
                Parameter("angle_offset", "real", "rad", "θ_0 per hysteresis run", self.n_hysteresis, True),
            )
        if self.n_te:
            out += (Parameter("te_offset", "real", "rad", "TE_0 per TE zero group (one: shared by all TE runs)", self.te_zero_groups, True),)
            if self.kinematic is not None:
                out += self.kinematic.parameters()
        if self.drift:
            out += drift_parameters(len(self.run_kinds), self.drift_shape)
        return out

    # --- one run -------------------------------------------------------------------------
    def _at_temperature(self, params, data):
        """(parameters with the friction level at the run's temperature, compliance factor)."""
        if self.temperature is None:
            return params, 1.0
        dT = data.temperature_delta_K
        return self.temperature.friction_params(params, dT), self.temperature.compliance_factor(params, dT)

    def _hysteresis_drive(self, params, data: HysteresisInput, run_index: int, hyst_index: int):
        """(applied torque, mesh torque, friction torque, creep, drift, offset) of one hysteresis run."""
        torque = data.torque_Nm
        if self.torque_offset:
            torque = torque - params["torque_offset"]
        if self.play_torque_offset:
            torque = torque - params["play_torque_offset"] * data.small_cycle
        z0 = jnp.atleast_1d(params["friction_start"])[hyst_index] if self.free_friction_start else None
        friction_params, _ = self._at_temperature(params, data)
        friction_torque = self.friction.friction_torque(friction_params, torque, self.scan, z0, data.time_s)
        mesh = torque - friction_torque
        zeros = jnp.zeros_like(torque)
        creep = zeros if self.creep is None else self.creep.twist(params, data.time_s, mesh, self.scan)
        drift = zeros
        if self.drift:
            drift = run_drift(params, run_index, data.time_s, self.drift_shape)
        offset = zeros + jnp.atleast_1d(params["angle_offset"])[hyst_index]
        return torque, mesh, friction_torque, creep, drift, offset

    def hysteresis_components(self, params, data: HysteresisInput, run_index: int, hyst_index: int):
        """Components (rad) of one hysteresis run, plus ``total``, ``mesh_torque`` and ``friction_state``."""
        torque, mesh, friction_torque, creep, drift, offset = self._hysteresis_drive(params, data, run_index, hyst_index)
        friction_params, factor = self._at_temperature(params, data)
        elastic = factor * self.compliance(params, torque)
        geometric = self.backlash(params, torque)
        friction = self._spring(params, factor, torque, mesh) + self._gap(params, mesh, hyst_index) - elastic - geometric
        creep = creep + self._gap_delay(params, data, mesh, hyst_index)
        zeros = jnp.zeros_like(torque)
        return self._finish(
            dict(elastic=elastic, friction=friction, geometric=geometric, creep=creep,
                 kinematic=zeros, drift=drift, offset=offset),
            mesh_torque=mesh,
            friction_state=friction_torque / friction_params["friction_torque"],
        )

    def hysteresis_total(self, params, data: HysteresisInput, run_index: int, hyst_index: int):
        """Measured output twist (rad) of one hysteresis run: the components' ``total`` without
        the parts that cancel in it (elastic + friction + geometric = spring and gap at the mesh
        torque) — what a fit evaluates, one compliance and one backlash pass fewer."""
        torque, mesh, _, creep, drift, offset = self._hysteresis_drive(params, data, run_index, hyst_index)
        _, factor = self._at_temperature(params, data)
        gap = self._gap(params, self._gap_torque(params, data, mesh), hyst_index)
        return self._spring(params, factor, torque, mesh) + gap + creep + drift + offset

    def _gap(self, params, gap_torque, hyst_index):
        """The gap's twist (rad) along a hysteresis run, its state carried from the run's start."""
        g0 = None
        if self.backlash.hysteretic and self.free_friction_start:
            g0 = jnp.atleast_1d(params["gap_start"])[hyst_index]
        return self.backlash.run_twist(params, gap_torque, self.scan, g0)

    def _spring(self, params, factor, torque, mesh):
        """Elastic twist (rad) at the mesh torque, a share of it at the applied torque when the
        compliance is partly ahead of the friction."""
        if self.series is None:
            return factor * self.compliance(params, mesh)
        return self.series.twist(params, lambda t: factor * self.compliance(params, t), torque, mesh)

    def _gap_torque(self, params, data, mesh):
        """The torque the gap sees (N·m): the mesh torque, lagged when the crossing is damped."""
        return mesh if self.gap_lag is None else self.gap_lag.gap_torque(params, data.time_s, mesh, self.scan)

    def _gap_delay(self, params, data, mesh, hyst_index):
        """What the damped gap crossing changes (rad): the gap at the lagged minus at the mesh
        torque — rate-dependent, booked with creep."""
        if self.gap_lag is None:
            return jnp.zeros_like(mesh)
        return self._gap(params, self._gap_torque(params, data, mesh), hyst_index) - self._gap(params, mesh, hyst_index)

    def te_components(self, params, data: TEInput, run_index: int):
        """Components (rad) of one TE run over its output angles, plus ``total`` and ``mesh_torque``."""
        phi = data.output_angle_rad
        ones = jnp.ones_like(phi)
        load = data.direction * jnp.abs(data.torque_Nm) * ones
        if self.torque_offset:
            # the sensor reads the load + offset: the true load magnitude is reduced by it
            load = data.direction * jnp.abs(data.torque_Nm - params["torque_offset"]) * ones
        friction_params, factor = self._at_temperature(params, data)
        friction_level = self.friction.sliding_level(friction_params, load)
        if self.speed is not None:
            friction_level = self.speed.friction_torque(params, friction_level, data.speed_rad_s)
            factor = factor * self.speed.compliance_factor(params, data.speed_rad_s)
        mesh = load + data.direction * friction_level

        def spring(t):
            return factor * self.compliance(params, t)

        elastic = spring(load)
        geometric = self.backlash(params, load)
        friction = self._spring(params, factor, load, mesh) + self.backlash(params, mesh) - elastic - geometric
        zeros = jnp.zeros_like(phi)
        creep = zeros if self.creep is None else self.creep.steady_twist(params, mesh)
        kinematic = zeros if self.kinematic is None else self.kinematic(params, phi)
        drift = zeros
        if self.drift:
            drift = run_drift(params, run_index, data.time_s, self.drift_shape)
        offset = zeros + jnp.atleast_1d(params["te_offset"])[data.zero_group]
        return self._finish(
            dict(elastic=elastic, friction=friction, geometric=geometric, creep=creep,
                 kinematic=kinematic, drift=drift, offset=offset),
            mesh_torque=mesh,
        )

    @staticmethod
    def _finish(parts, **extra):
        total = sum(parts[k] for k in COMPONENTS)
        return {**parts, "total": total, **extra}

    # --- the campaign --------------------------------------------------------------------
    def _each_run(self, inputs, hysteresis, te) -> list:
        """``hysteresis(data, run_index, hyst_index)`` / ``te(data, run_index)`` of every run;
        ``inputs`` in campaign order (HysteresisInput / TEInput)."""
        if len(inputs) != len(self.run_kinds):
            raise ValueError(f"model has {len(self.run_kinds)} runs, got {len(inputs)} inputs")
        out, h = [], 0
        for i, (kind, data) in enumerate(zip(self.run_kinds, inputs)):
            if kind == "hysteresis":
                out.append(hysteresis(data, i, h))
                h += 1
            else:
                out.append(te(data, i))
        return out

    def components(self, params, inputs) -> list[dict]:
        """Components of every run; ``inputs`` in campaign order (HysteresisInput / TEInput)."""
        return self._each_run(inputs, lambda d, i, h: self.hysteresis_components(params, d, i, h),
                              lambda d, i: self.te_components(params, d, i))

    def predict(self, params, inputs) -> list:
        """Predicted measured angle (rad) per run: output twist or TE (the components' ``total``
        to rounding)."""
        te_index = [i for i, k in enumerate(self.run_kinds) if k == "transmission_error"]
        if len(te_index) < 2 or self.drift:  # drift reads each run's own time origin and span
            return self._each_run(inputs, lambda d, i, h: self.hysteresis_total(params, d, i, h),
                                  lambda d, i: self.te_components(params, d, i)["total"])
        out = self._each_run(inputs, lambda d, i, h: self.hysteresis_total(params, d, i, h), lambda d, i: None)
        te = [inputs[i] for i in te_index]
        total = self.te_components(params, _concatenate_te(te), -1)["total"]
        for i, part in zip(te_index, jnp.split(total, np.cumsum([d.output_angle_rad.shape[0] for d in te])[:-1])):
            out[i] = part
        return out


def _concatenate_te(runs) -> TEInput:
    """Several TE runs as one: samples concatenated, each run's scalars (load, speed, direction,
    zero group, temperature) spread over its samples. A TE run's model is a function of each
    sample and its run's scalars alone, so every TE run of a campaign evaluates as one — one
    program of a fixed size, where one per run made XLA's compile time grow with the runs."""
    lengths = np.array([d.output_angle_rad.shape[0] for d in runs])

    def spread(field):
        return jnp.concatenate([jnp.broadcast_to(getattr(d, field), (n,)) for d, n in zip(runs, lengths)])

    return TEInput(
        jnp.concatenate([d.output_angle_rad for d in runs]), jnp.concatenate([d.time_s for d in runs]),
        spread("torque_Nm"), spread("speed_rad_s"), spread("direction"), spread("zero_group"),
        spread("temperature_delta_K"))
