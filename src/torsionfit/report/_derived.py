"""Catalog metrics from the model (DESIGN §1.4), for any parameter draw: the fitted model is
run through the paper's five-step protocol and the TE conditions of the campaign, noise-free,
and the metrics are read off exactly. Vectorised over draws.

The loop is the fitted model's, at the slowest loading rate the campaign's hysteresis runs
declare (else the rate read off the data's largest cycles; T_r/100 per second without
hysteresis cycles), started at rest (friction state 0, no offset, no drift).

``play`` and ``stiffness_loading`` are read, with the data-only definitions
(``metrics.play_from_arrays``, ``metrics.loading_compliance_from_arrays``), off the model's
noise-free prediction of the data's own record (``report/_record.py``), started from that
run's fitted state at its first sample, its torque-sensor offset applied (the record did not
start at rest; no angle offset or drift: the definitions do not read them).
"""

import dataclasses
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._x64 import in_float64
from .. import model as m
from .._chunks import CHUNK, map_chunks
from ..io import Campaign
from ..metrics._campaign import reference_run_for
from .._errors import InputError
from ..metrics._hysteresis import CLASS_METRICS, class_loading_rate
from ..metrics._te import TE_WINDOW_DEG, in_te_window, te_reading
from ..units import ANGLE_UNITS, SPEED_UNITS, STIFFNESS_UNITS
from ._record import RecordReader, record_classes, record_params, record_reader

ARCMIN = ANGLE_UNITS["arcmin"]
NM_PER_ARCMIN = STIFFNESS_UNITS["Nm/arcmin"]
#: samples per protocol step (0 → ±T_r), on top of the levels the metrics read (0, ±x·T_r),
#: which are samples themselves. Friction's one-sample update is exact for any step along a
#: monotone ramp and the other parts are functions of the torque, so the loop is exact at every
#: sample and no metric is read between samples; the step only sets the loop area's trapezoid
#: error (~1e-5 relative). Creep is a time recurrence (zero-order hold): finer steps with it.
SAMPLES_PER_STEP = 400
SAMPLES_PER_STEP_CREEP = 2000
#: draws × protocol samples per compiled call: the chunk that keeps a call's loops within this
#: ran fastest (measured: 16 draws of 10 006 samples, 128 of 2 006)
CHUNK_SAMPLES = 2**18


def _draws_per_call(n_samples: int) -> int:
    return max(CHUNK, 2 ** int(np.log2(max(1, CHUNK_SAMPLES // n_samples))))


@dataclass(frozen=True)
class MetricSpec:
    name: str
    unit: str
    description: str
    condition: dict | None = None


class _Protocol(eqx.Module):
    """The noise-free five-step loop the metrics are read from (0 → +T_r → 0 → −T_r → 0 →
    +T_r at a constant loading rate, as ``bench.five_step_protocol``)."""

    time_s: jnp.ndarray
    torque_Nm: jnp.ndarray
    i2: int = eqx.field(static=True)  # end of step 2 (τ = 0, coming down)
    i3: int = eqx.field(static=True)  # end of step 3 (τ = −T_r)
    i4: int = eqx.field(static=True)  # end of step 4 (τ = 0, going up)
    i5: int = eqx.field(static=True)  # end of step 5 (τ = +T_r)


def _protocol(rated, rate, samples_per_step: int, lost_motion_fraction: float) -> _Protocol:
    """The loop sampled at ``samples_per_step`` even torque levels per step plus ±x·T_r (x the
    lost-motion fraction), so every level a metric reads is a sample: one sample more per step
    whatever x is, so x is data, not a compile key (a level already on the grid repeats, which
    leaves every state as it is)."""
    up = np.sort(np.append(np.linspace(0.0, rated, samples_per_step + 1), lost_motion_fraction * rated))
    steps = [up, up[::-1], -up, -up[::-1], up]
    tau = np.concatenate([steps[0]] + [s[1:] for s in steps[1:]])
    t = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(tau)) / rate)])
    k = len(up) - 1  # samples per step after the first
    return _Protocol(jnp.asarray(t), jnp.asarray(tau), 2 * k, 3 * k, 4 * k, 5 * k)


#: linear parameters the metrics read: the reducer's kinematic error is a property of the unit;
#: the others (per-run offsets, drift) belong to one measured run and are zero in the metrics' runs
METRIC_LINEAR = ("kin_cos", "kin_sin")


def _single_run_params(model: m.CampaignModel, params: dict) -> dict:
    """Parameters of ``model`` (a one-run model) from a campaign's: per-run entries replaced by
    a run at rest (no offset, no drift, friction state 0, no torque-sensor offset). Needs of
    ``params`` only the physics and the ``METRIC_LINEAR`` entries."""
    out = {}
    for p in model.parameters():
        if p.name in m.RUN_START_STATES or (p.linear and p.name not in METRIC_LINEAR):
            out[p.name] = jnp.zeros(p.size)  # the protocol starts at rest; no run offsets
        elif p.name == "torque_offset":
            out[p.name] = jnp.asarray(0.0)
        else:
            out[p.name] = params[p.name]
    return out


def _te_metric_grid(window_points: int = 41, revolution_points: int = 720):
    """Output angles (rad) the model's TE metrics are read at, with ``te_reading``'s window flags
    and revolution weights: ``window_points`` evenly over the 180° window (weight 0) then
    ``revolution_points`` evenly over one revolution (window flag 0, equal weights) — the
    continuous limit of the data's samples."""
    half = np.deg2rad(TE_WINDOW_DEG)
    window = np.pi + np.linspace(-half, half, window_points)
    revolution = np.linspace(0.0, 2 * np.pi, revolution_points + 1)[:-1]
    phi = np.concatenate([window, revolution])
    in_window = np.concatenate([in_te_window(window), np.zeros(revolution_points)])
    weight = np.concatenate([np.zeros(window_points), np.ones(revolution_points)])
    return phi, in_window, weight


_TE_GRID = _te_metric_grid()


class DerivedMetrics(eqx.Module):
    """Metric values (one vector per draw) of a campaign's model. Build with
    :func:`derived_metrics_for`, evaluate with ``evaluate(values)`` or ``over_draws``."""

    hyst_model: m.CampaignModel
    te_model: m.CampaignModel | None
    protocol: _Protocol
    te_inputs: list
    record: RecordReader | None
    specs: tuple = eqx.field(static=True)
    # arrays, not static fields: a static value is part of the compile key, and a batch of units
    # with other rated torques would compile the metrics anew for each
    rated: jnp.ndarray  # T_r, N·m
    lost_motion_fraction: jnp.ndarray  # x of the lost motion at ±x·T_r
    #: directions (+1, −1) with a no-load TE run in the campaign: K_d there is against the no-load TE
    te_reference_directions: tuple = eqx.field(static=True, default=())
    #: why ``play`` is not among the record's metrics (the play ramps form no loop); None: it is
    play_note: str | None = eqx.field(static=True, default=None)
    #: why the loading slope is not (the stiffness ramps form no loop); None: it is
    loading_note: str | None = eqx.field(static=True, default=None)

    def not_read_notes(self) -> dict[str, str]:
        """``{metric: why}`` of the class metrics the data's record gives no reading of."""
        out = {} if self.play_note is None else {"play": self.play_note}
        if self.loading_note is not None:
            out |= {name: self.loading_note for name in CLASS_METRICS[1:]}
        return out

    def evaluate(self, values: dict) -> jnp.ndarray:
        """All metrics (in ``specs`` order, their units) for one parameter set (SI)."""
        p = self.protocol
        params = _single_run_params(self.hyst_model, values)
        c = self.hyst_model.components(params, [m.hysteresis_input(p.time_s, p.torque_Nm)])[0]
        theta, tau = c["total"], p.torque_Nm
        # full branches between −T_r and +T_r: down = steps 2+3 (reversed so τ rises), up = 4+5
        i1 = p.i2 // 2  # end of step 1 (τ = +T_r)
        dn_t, dn_y = tau[p.i3:i1 - 1:-1], theta[p.i3:i1 - 1:-1]
        u_t, u_y = tau[p.i3:p.i5 + 1], theta[p.i3:p.i5 + 1]

        def at(t_branch, y_branch, level):
            return jnp.interp(level, t_branch, y_branch)

        x = self.lost_motion_fraction * self.rated
        mid0 = 0.5 * (at(dn_t, dn_y, 0.0) + at(u_t, u_y, 0.0))
        rated_twist = theta[p.i5] - mid0
        rated_twist_start = theta[p.i5] - theta[0]
        lost = 0.5 * (at(dn_t, dn_y, x) + at(u_t, u_y, x)) - 0.5 * (at(dn_t, dn_y, -x) + at(u_t, u_y, -x))
        backlash = at(dn_t, dn_y, 0.0) - at(u_t, u_y, 0.0)
        energy = jnp.trapezoid(dn_y, dn_t) - jnp.trapezoid(u_y, u_t)  # ∮ θ dτ, each branch on its own samples
        slope = jax.grad(lambda t: self.hyst_model.compliance(params, t))(jnp.asarray(self.rated))
        parts = [c["elastic"][p.i5], c["friction"][p.i5], c["geometric"][p.i5]]
        if self.hyst_model.creep is not None:
            parts.append(c["creep"][p.i5])
        out = [
            self.rated / rated_twist / NM_PER_ARCMIN,
            self.rated / rated_twist_start / NM_PER_ARCMIN,
            1.0 / slope / NM_PER_ARCMIN,
            lost / ARCMIN,
            backlash / ARCMIN,
            energy,
            values["gap"] / ARCMIN,
            values["friction_torque"],
        ]
        if _three_segment(self.hyst_model):
            out.append((values["gap"] + first_segment_twist(values)) / ARCMIN)
        out += [q / ARCMIN for q in parts]
        if self.record is not None:
            # the data's own record: from its run's fitted state at the first sample, not from rest
            play, c_pos, c_neg = self.record.read(
                self.hyst_model, [record_params(self.hyst_model, params, values, k) for k in self.record.run_index])
            deg = ANGLE_UNITS["deg"]
            out += [play / ARCMIN] if self.play_note is None else []
            if self.loading_note is None:
                out += [2.0 / (c_pos + c_neg) / NM_PER_ARCMIN, c_pos / deg, c_neg / deg]
        if self.te_model is not None:
            in_window, weight = _TE_GRID[1], _TE_GRID[2]
            for loaded, reference in self.te_inputs:
                te = self._te_twist(values, loaded)
                ref = jnp.zeros_like(te) if reference is None else self._te_twist(values, reference)
                _, _, kinematic_180, kd, kt = te_reading(loaded.torque_Nm, te, ref, in_window, weight,
                                                         has_reference=reference is not None)
                out += [kd / NM_PER_ARCMIN, kt / NM_PER_ARCMIN, kinematic_180 / ARCMIN]
        return jnp.stack([jnp.asarray(v, float) for v in out])

    def reads_linear(self) -> bool:
        """Whether the metrics read linear parameters (the kinematic harmonics of TE runs): only
        then do the draws' values need the linear profile (a model run over the data per draw)."""
        models = [self.hyst_model] + ([self.te_model] if self.te_model is not None else [])
        return any(p.name in METRIC_LINEAR for mod in models for p in mod.parameters())

    def _te_twist(self, values: dict, inp: m.TEInput) -> jnp.ndarray:
        """Model TE (rad) of one TE condition against the unloaded, friction-free zero."""
        tc = self.te_model.components(_single_run_params(self.te_model, values), [inp])[0]
        return tc["total"] - tc["offset"]

    def _kernel(self) -> "DerivedMetrics":
        """This without its texts: what the compiled programs see. The texts name the loading
        rate; as part of the compile key they would compile the metrics anew per rate."""
        return dataclasses.replace(self, specs=())

    @in_float64
    def over_draws(self, values_batch: dict) -> np.ndarray:
        """(draws, metrics) for a dict of stacked parameter draws."""
        kernel = self._kernel()
        chunk = _draws_per_call(self.protocol.torque_Nm.shape[0] + (self.record.n_samples if self.record is not None else 0))
        return map_chunks(lambda v: _metrics_over_draws(kernel, v), values_batch, chunk)

    @in_float64
    def kd_over_draws(self, values_batch: dict, torque_Nm, speed_rpm, direction) -> np.ndarray:
        """K_d = τ / TE(180°) (N·m/arcmin) of the model at any TE conditions, read as ``kd_mean``
        (``metrics.te_reading`` over the 180° window): (draws, conditions) for stacked parameter
        draws and 1-D arrays of load torque (N·m), output speed (rpm) and direction (+1 forward,
        −1 backward). The reference is the model's no-load TE at the condition's speed and
        direction when the campaign has a no-load TE run in that direction, else the model's
        zero. Needs TE runs in the campaign (``te_model``), since only they carry TE-only
        physics such as speed terms."""
        if self.te_model is None:
            raise ValueError("K_d needs a campaign with TE runs")
        speed_rad_s = jnp.asarray(speed_rpm, float) * SPEED_UNITS["rpm"]
        d = jnp.asarray(direction, float)
        has_ref = jnp.where(d > 0, 1.0 * (1 in self.te_reference_directions), 1.0 * (-1 in self.te_reference_directions))
        conditions = (jnp.asarray(torque_Nm, float), speed_rad_s, d, has_ref)
        kernel = self._kernel()
        return map_chunks(lambda v: _kd_over_draws(kernel, v, *conditions), values_batch)


@eqx.filter_jit
def _metrics_over_draws(derived: DerivedMetrics, values_batch: dict):
    return jax.vmap(derived.evaluate)(values_batch)


@eqx.filter_jit
def _kd_over_draws(derived: DerivedMetrics, values_batch: dict, torque_Nm, speed_rad_s, direction, has_ref):
    # the 180° window of the metrics' grid: K_d reads nothing else
    inside = _TE_GRID[1] > 0
    phi = jnp.asarray(_TE_GRID[0][inside])
    t0, in_window = jnp.zeros(phi.shape), jnp.ones(phi.shape)

    def one(values, tau, v, d, r):
        te = derived._te_twist(values, m.TEInput(phi, t0, tau, v, d))
        ref = r * derived._te_twist(values, m.TEInput(phi, t0, jnp.zeros_like(tau), v, d))
        # has_reference only picks the kinematic part's source, which K_d does not read
        kd = te_reading(tau, te, ref, in_window, in_window, has_reference=True)[3]
        return kd / NM_PER_ARCMIN

    per_draw = jax.vmap(one, in_axes=(None, 0, 0, 0, 0))
    return jax.vmap(lambda values: per_draw(values, torque_Nm, speed_rad_s, direction, has_ref))(values_batch)


def _three_segment(model) -> bool:
    return isinstance(model.compliance, m.ThreeSegmentCompliance)


def first_segment_twist(params: dict):
    """2·T1·(1/K1 − 1/K2), floored at 0: what a three-segment compliance's first segment adds
    across zero torque beyond the second segment's line (rad)."""
    return jnp.maximum(2.0 * params["t1"] * (1.0 / params["k1"] - 1.0 / params["k2"]), 0.0)


@in_float64
def derived_metrics_for(campaign: Campaign, model: m.CampaignModel, lost_motion_pct: float = 3.0) -> DerivedMetrics:
    """Metric definitions and evaluation machinery for ``campaign`` fitted with ``model``."""
    rated = campaign.reducer.rated_torque_Nm
    classes = record_classes(campaign)
    rates = [r.loading_rate_Nm_per_s for r in campaign.hysteresis_runs if r.loading_rate_Nm_per_s]
    # a rate the manifest does not declare is read off the data's largest cycles
    data_rate = None if classes is None else class_loading_rate(classes.large_classes, classes.large, classes.large_run.time_s)
    rate = min(rates) if rates else data_rate or rated / 100.0
    hyst_model = dataclasses.replace(model, run_kinds=("hysteresis",))
    specs = [
        MetricSpec("stiffness_rated", "Nm/arcmin", f"secant T_r/(θ(T_r) − θ_mid(0)) of the model's five-step loop at {rate:g} N·m/s, midpoint reference"),
        MetricSpec("stiffness_rated_from_start", "Nm/arcmin", "the same secant against the angle at the start of step 1 (the paper's protocol reference)"),
        MetricSpec("stiffness_elastic", "Nm/arcmin", "elastic slope dτ/dθ_e of the compliance curve at T_r, without friction and lost motion"),
        MetricSpec("lost_motion", "arcmin", f"twist between the model loop's midpoints at ±{lost_motion_pct:g} % of T_r"),
        MetricSpec("backlash", "arcmin", "model loop width at zero torque (GB/T 35089; Harmonic Drive: 'hysteresis loss')"),
        MetricSpec("dissipated_energy", "J", "model loop area per cycle, ±T_r"),
        MetricSpec("geometric_gap", "arcmin", "geometric gap β of the mesh (model only)"),
        MetricSpec("friction_torque", "Nm", "Coulomb friction level T_f (model only)"),
        *([MetricSpec("gap_with_first_segment", "arcmin",
                      "geometric gap β plus the twist the compliance's first segment adds across zero torque beyond "
                      "the second segment's line, 2·T1·(1/K1 − 1/K2) when positive (model only): the gap-like lost "
                      "motion where a soft first segment shares the gap's crossing")]
          if _three_segment(model) else []),
        MetricSpec("twist_elastic_at_rated", "arcmin", "elastic part of the angle at T_r (end of step 5)"),
        MetricSpec("twist_friction_at_rated", "arcmin", "friction part of the angle at T_r (end of step 5)"),
        MetricSpec("twist_geometric_at_rated", "arcmin", "geometric part of the angle at T_r (end of step 5)"),
    ]
    if model.creep is not None:
        specs.append(MetricSpec("twist_creep_at_rated", "arcmin", "creep part of the angle at T_r (end of step 5)"))
    record = None
    if classes is not None:
        try:
            record = record_reader(classes, campaign.hysteresis_runs)
        except InputError:  # a branch too short to bin: no class metrics from the model (the data's notes say why)
            classes = None
    if classes is not None:
        runs = (f"run {classes.small_run.name!r}" if classes.large_run is classes.small_run
                else f"runs {classes.small_run.name!r} and {classes.large_run.name!r}")
        where = (f"the model's noise-free prediction of the data's own record ({runs}, from the fitted state at its first "
                 f"sample), read as the data "
                 f"are: the ±{classes.small.amplitude_Nm:.3g} N·m cycles for the play, the ±{classes.large.amplitude_Nm:.3g} N·m "
                 f"cycles for the loading slope")
        if classes.play_note is None:
            specs.append(MetricSpec("play", "arcmin", f"loop width at zero torque of the smallest cycles: {where}"))
        else:  # the play ramps form no loop: the width of the smallest full cycles stands in
            where += " (their width stands for the play the loading slope starts past; no play: " + classes.play_note + ")"
        if classes.loading_note is None:
            specs += [
                MetricSpec("stiffness_loading", "Nm/arcmin", "1 / mean of the + and − loading-branch compliances of the largest cycles, beyond half the play from the loop centre up to the peak (the data authors' definition), "
                           + where),
                MetricSpec("compliance_loading_pos", "deg/Nm", "loading compliance of the + side (increasing torque, τ > 0), as stiffness_loading"),
                MetricSpec("compliance_loading_neg", "deg/Nm", "loading compliance of the − side (decreasing torque, τ < 0), as stiffness_loading"),
            ]
    te_model, te_inputs, ref_directions = None, [], ()
    if campaign.te_runs:
        te_model = dataclasses.replace(model, run_kinds=("transmission_error",))
        phi = _TE_GRID[0]
        ref_directions = tuple(sorted({int(r.direction) for r in campaign.te_runs if r.torque_Nm == 0}))
        for run in campaign.te_runs:
            if run.torque_Nm == 0:
                continue  # a no-load run has no stiffness: it is the reference of the others
            cond = {"torque_Nm": run.torque_Nm, "speed_rpm": run.speed_rpm,
                    "direction": "forward" if run.direction > 0 else "backward"}
            reference = reference_run_for(campaign, run)
            against = (f"against the model's no-load TE at the reference run {reference.name!r}'s condition "
                       f"({reference.speed_rpm:g} rpm, same direction), the kinematic error removed"
                       if reference is not None else
                       "against the model's zero (no no-load run in the same direction), the kinematic error included")
            te_inputs.append((m.te_input(phi, run.torque_Nm, run.speed_rpm, run.direction),
                              None if reference is None else m.te_input(phi, 0.0, reference.speed_rpm, run.direction)))
            window = f"model TE − ref averaged within ±{TE_WINDOW_DEG:g}° of 180° output angle"
            specs.append(MetricSpec(f"kd_mean[{run.name}]", "Nm/arcmin", f"K_d = |T| / |TE(180°) − ref|: {window}, {against}", cond))
            specs.append(MetricSpec(f"kt[{run.name}]", "Nm/arcmin", f"K_t = |T| / |revolution-mean TE − ref|, model, {against}", cond))
            specs.append(MetricSpec(f"te_kinematic_180[{run.name}]", "arcmin",
                                    "kinematic part of the model TE at 180° (window mean minus revolution mean of the "
                                    + ("reference" if reference is not None else "run's own TE") + "), as the data-only te_kinematic_180", cond))
    steps = SAMPLES_PER_STEP if model.creep is None else SAMPLES_PER_STEP_CREEP
    protocol = _protocol(rated, rate, steps, lost_motion_pct / 100.0)
    return DerivedMetrics(hyst_model, te_model, protocol, te_inputs, record, tuple(specs), jnp.asarray(float(rated)),
                          jnp.asarray(lost_motion_pct / 100.0), ref_directions,
                          play_note=None if classes is None else classes.play_note,
                          loading_note=None if classes is None else classes.loading_note)
