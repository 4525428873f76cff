"""Catalog metrics from the model (DESIGN §1.4), for any parameter draw: the fitted model is
run through the paper's five-step protocol and the TE conditions of the campaign, noise-free,
and the metrics are read off exactly. Vectorised over draws.

The loop is the fitted model's, at the slowest loading rate of the campaign (or T_r/100 per
second without hysteresis runs), started at rest (friction state 0, no offset, no drift).

``play`` and ``stiffness_loading`` are read, with the data-only definitions
(``metrics.play_from_arrays``, ``metrics.loading_compliance_from_arrays``), off a second
noise-free record shaped like the measured one: small cycles at the amplitude of the data's
smallest cycles (its play ramps) followed by large cycles at the amplitude of its largest
(its stiffness ramps), started at rest.
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
from ..metrics._hysteresis import LOADING_FIT_TOP, grouped_cycles
from ..metrics._te import TE_WINDOW_DEG, in_te_window, te_reading
from ..units import ANGLE_UNITS, SPEED_UNITS, STIFFNESS_UNITS

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


#: samples per leg (peak to peak) of the play and stiffness cycles of the bench record (the
#: levels read are samples; the loading slopes are least squares over them); cycles
#: of each: the metrics read the last one, the ones before settle the friction state
BENCH_SAMPLES_PER_LEG = 100
BENCH_SMALL_CYCLES = 3
BENCH_LARGE_CYCLES = 2


class _BenchRecord(eqx.Module):
    """Play cycles then stiffness cycles, as a bench runs them: 0 → +a → −a … then 0 → +A →
    −A …, each leg through τ = 0 exactly. ``small``/``large``: (down start, up start, up end)
    sample indices of the last cycle of each (down: +peak → −peak, up: −peak → +peak)."""

    time_s: jnp.ndarray
    torque_Nm: jnp.ndarray
    small: tuple = eqx.field(static=True)
    large: tuple = eqx.field(static=True)


def _bench_record(small_Nm: float, large_Nm: float, rate: float) -> _BenchRecord:
    n = BENCH_SAMPLES_PER_LEG  # even: a peak-to-peak leg has τ = 0 as its middle sample
    knots = [0.0]
    for amp, cycles in ((small_Nm, BENCH_SMALL_CYCLES), (large_Nm, BENCH_LARGE_CYCLES)):
        if knots[-1] != 0.0:
            knots.append(0.0)
        knots += [amp, -amp] * cycles + [amp]
    legs = [np.linspace(a, b, n + 1 if abs(a) == abs(b) and a else n // 2 + 1) for a, b in zip(knots[:-1], knots[1:])]
    tau = np.concatenate([legs[0]] + [leg[1:] for leg in legs[1:]])
    t = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(tau)) / rate)])
    ends = np.cumsum([len(leg) - 1 for leg in legs])  # index of each knot after the first
    small_end = 1 + 2 * BENCH_SMALL_CYCLES  # knots: 0, a, −a, …, a
    last = len(knots) - 1
    small = (int(ends[small_end - 3]), int(ends[small_end - 2]), int(ends[small_end - 1]))
    large = (int(ends[last - 3]), int(ends[last - 2]), int(ends[last - 1]))
    return _BenchRecord(jnp.asarray(t), jnp.asarray(tau), small, large)


def _loop_at_zero(theta, tau, idx):
    """(down, up) angle at τ = 0 of the cycle with (down start, up start, up end) ``idx``."""
    d0, u0, u1 = idx
    return theta[(d0 + u0) // 2], theta[(u0 + u1) // 2]


def _loading_compliance(theta, tau, idx, centre, play, peak):
    """Least-squares dθ/dτ of the loading parts of one cycle (up branch at τ > 0, down branch
    at τ < 0) beyond half the play from the loop centre, up to 90 % of the peak: (pos, neg)."""
    d0, u0, u1 = idx

    def slope(t, y):
        w = ((jnp.abs(y - centre) > 0.5 * play) & (jnp.abs(t) <= LOADING_FIT_TOP * peak) & (jnp.abs(t) > 0)).astype(t.dtype)
        sw = jnp.maximum(jnp.sum(w), 1.0)
        tm, ym = jnp.sum(w * t) / sw, jnp.sum(w * y) / sw
        return jnp.sum(w * (t - tm) * (y - ym)) / jnp.maximum(jnp.sum(w * (t - tm) ** 2), 1e-300)

    mid_up, mid_dn = (u0 + u1) // 2, (d0 + u0) // 2
    return slope(tau[mid_up:u1 + 1], theta[mid_up:u1 + 1]), slope(tau[mid_dn:u0 + 1], theta[mid_dn:u0 + 1])


#: linear parameters the metrics read: the reducer's kinematic error is a property of the unit;
#: the others (per-run offsets, drift) belong to one measured run and are zero in the metrics' runs
METRIC_LINEAR = ("kin_cos", "kin_sin")


def _single_run_params(model: m.CampaignModel, params: dict) -> dict:
    """Parameters of ``model`` (a one-run model) from a campaign's: per-run entries replaced by
    a run at rest (no offset, no drift, friction state 0, no torque-sensor offset). Needs of
    ``params`` only the physics and the ``METRIC_LINEAR`` entries."""
    out = {}
    for p in model.parameters():
        if p.name == "friction_start" or (p.linear and p.name not in METRIC_LINEAR):
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
    bench: _BenchRecord | None
    specs: tuple = eqx.field(static=True)
    # arrays, not static fields: a static value is part of the compile key, and a batch of units
    # with other rated torques would compile the metrics anew for each
    rated: jnp.ndarray  # T_r, N·m
    lost_motion_fraction: jnp.ndarray  # x of the lost motion at ±x·T_r
    #: directions (+1, −1) with a no-load TE run in the campaign: K_d there is against the no-load TE
    te_reference_directions: tuple = eqx.field(static=True, default=())

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
        ] + [q / ARCMIN for q in parts]
        if self.bench is not None:
            out += self._bench_metrics(params)
        if self.te_model is not None:
            in_window, weight = _TE_GRID[1], _TE_GRID[2]
            for loaded, reference in self.te_inputs:
                te = self._te_twist(values, loaded)
                ref = jnp.zeros_like(te) if reference is None else self._te_twist(values, reference)
                _, _, kinematic_180, kd, kt = te_reading(loaded.torque_Nm, te, ref, in_window, weight,
                                                         has_reference=reference is not None)
                out += [kd / NM_PER_ARCMIN, kt / NM_PER_ARCMIN, kinematic_180 / ARCMIN]
        return jnp.stack([jnp.asarray(v, float) for v in out])

    def _bench_metrics(self, params) -> list:
        """``play`` (arcmin), ``stiffness_loading`` (N·m/arcmin) and the two loading
        compliances (deg/N·m) off the bench record, with the data-only definitions."""
        b = self.bench
        theta = self.hyst_model.predict(params, [m.hysteresis_input(b.time_s, b.torque_Nm)])[0]
        down, up = _loop_at_zero(theta, b.torque_Nm, b.small)
        play = down - up
        centre = 0.5 * sum(_loop_at_zero(theta, b.torque_Nm, b.large))
        peak = jnp.max(jnp.abs(b.torque_Nm))
        c_pos, c_neg = _loading_compliance(theta, b.torque_Nm, b.large, centre, play, peak)
        deg = ANGLE_UNITS["deg"]
        return [play / ARCMIN, 2.0 / (c_pos + c_neg) / NM_PER_ARCMIN, c_pos / deg, c_neg / deg]

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
        chunk = _draws_per_call(self.protocol.torque_Nm.shape[0])
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


@in_float64
def derived_metrics_for(campaign: Campaign, model: m.CampaignModel, lost_motion_pct: float = 3.0) -> DerivedMetrics:
    """Metric definitions and evaluation machinery for ``campaign`` fitted with ``model``."""
    rated = campaign.reducer.rated_torque_Nm
    rates = [r.loading_rate_Nm_per_s for r in campaign.hysteresis_runs if r.loading_rate_Nm_per_s]
    rate = min(rates) if rates else rated / 100.0
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
        MetricSpec("twist_elastic_at_rated", "arcmin", "elastic part of the angle at T_r (end of step 5)"),
        MetricSpec("twist_friction_at_rated", "arcmin", "friction part of the angle at T_r (end of step 5)"),
        MetricSpec("twist_geometric_at_rated", "arcmin", "geometric part of the angle at T_r (end of step 5)"),
    ]
    if model.creep is not None:
        specs.append(MetricSpec("twist_creep_at_rated", "arcmin", "creep part of the angle at T_r (end of step 5)"))
    bench = None
    amplitudes = _data_amplitudes(campaign)
    if amplitudes is not None:
        small, large = amplitudes
        bench = _bench_record(small, large, rate)
        record = f"the model's record of {BENCH_SMALL_CYCLES} cycles at ±{small:.3g} N·m then {BENCH_LARGE_CYCLES} at ±{large:.3g} N·m (the data's smallest and largest cycles)"
        specs += [
            MetricSpec("play", "arcmin", f"loop width at zero torque of the smallest cycles: {record}"),
            MetricSpec("stiffness_loading", "Nm/arcmin", "1 / mean of the + and − loading-branch compliances of the largest cycles, beyond half the play from the loop centre up to 90 % of the peak (the data authors' definition), "
                       + record),
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
    return DerivedMetrics(hyst_model, te_model, protocol, te_inputs, bench, tuple(specs), jnp.asarray(float(rated)),
                          jnp.asarray(lost_motion_pct / 100.0), ref_directions)


def _data_amplitudes(campaign: Campaign) -> tuple[float, float] | None:
    """(smallest, largest) cycle amplitude (N·m) over the campaign's hysteresis runs, as the
    data-only metrics group them; None without a run whose cycles can be grouped."""
    groups = grouped_cycles(campaign.hysteresis_runs)
    if not groups:
        return None
    return min(g.smallest.amplitude_Nm for g in groups), max(g.largest.amplitude_Nm for g in groups)
