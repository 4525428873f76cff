"""The effects catalog (DESIGN §3): each effect pairs a residual signature with a model
extension. Adding an effect is one new subclass of :class:`Effect` here, listed in
``CATALOG``."""

import abc
import dataclasses
from dataclasses import dataclass, replace

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..fit import temperatures_resolving_friction
from ..fit._prior import first_look_ramp_time_s
from ..metrics import gap_crossings
from ..model import (RELAY_FLANK_SHARE, DahlFriction, HeldGapBacklash, MaxwellSlipFriction, RelayGapBacklash, SmoothBacklash, TemperatureDependence as TemperatureTerm,
                     GapLag as GapLagTerm)
from ..model._drift import WARM_UP_FRACTIONS
from ..model._effects import DEFAULT_FRICTION_ELEMENTS
from ._context import FitContext
from ._signature import Evidence, regression_evidence

#: kinematic orders searched in TE residuals (per output revolution)
MAX_KINEMATIC_ORDER = 120


class Effect(abc.ABC):
    """A physical effect the base model lacks."""

    name: str = ""
    signature_text: str = ""
    extension_text: str = ""
    #: the extension can grow after it is added (more kinematic orders): keep testing it
    growable: bool = False
    #: catalog effects that are alternatives to this one for the same component (a lag or a
    #: memory of the friction level's load): once this one is added, each is refitted in its
    #: place, and the better kept
    rivals: tuple[str, ...] = ()
    #: catalog effects this one contains as a special case (the held gap is one relay): where
    #: both earn their keep in one step, this one is kept only when it earns its keep over the
    #: one it contains
    nests: tuple[str, ...] = ()

    def applicable(self, ctx: FitContext) -> bool:
        return True

    @abc.abstractmethod
    def signature(self, ctx: FitContext, alpha: float) -> Evidence:
        """Evidence for the effect in the residuals of ``ctx``."""

    @abc.abstractmethod
    def extend(self, effects: dict, evidence: Evidence, ctx: FitContext) -> dict:
        """The ``effects`` switches with this effect's extension added."""

    def start_values(self, evidence: Evidence) -> dict:
        """Values (SI) of the extension's new scalar parameters where the signature found the
        effect, tried as a further start of its refit besides the nested one; none by default."""
        return {}

    def rival_start_values(self, ctx: FitContext) -> dict:
        """Values (SI) of the extension's new scalar parameters to start from when it is refitted
        in a rival's place (no signature of its own to say where); none by default."""
        return {}

    def rival_applicable(self, ctx: FitContext) -> bool:
        """Whether the extension can be refitted in a rival's place on ``ctx``, the fit the rival
        was added to (not :meth:`applicable`: a friction level's lag replaces its memory with the
        load dependence the memory brought); always by default."""
        return True


def _t(run, ctx):
    return run.mesh_torque_Nm / ctx.rated_torque_Nm


class StiffnessNonlinearity(Effect):
    name = "stiffness_nonlinearity"
    signature_text = "smooth curvature of the residual versus mesh torque (odd powers τ³, τ⁵)"
    extension_text = "three-segment compliance (K1, K2, K3 with smooth knees)"

    def signature(self, ctx, alpha):
        cols = [np.stack([_t(r, ctx) ** 3, _t(r, ctx) ** 5], axis=1) for r in ctx.runs]
        return regression_evidence(self.name, ctx.runs, cols, "residual curves with mesh torque (τ³, τ⁵ terms)")

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: "three_segment"}


class RateDependence(Effect):
    name = "rate_dependence"
    signature_text = "residual that grows with the loading rate dτ/dt, across loops run at different rates"
    extension_text = "creep element (K_c, T_c)"

    def _rates(self, ctx):
        out = []
        for r in ctx.hysteresis:
            rate = np.gradient(r.drive_torque_Nm, r.time_s, edge_order=1) if np.all(np.diff(r.time_s) > 0) else None
            if rate is None:  # duplicate stamps: differentiate over sample index, scale by mean step
                dt = (r.time_s[-1] - r.time_s[0]) / max(len(r.time_s) - 1, 1)
                rate = np.gradient(r.drive_torque_Nm) / max(dt, 1e-12)
            out.append(rate)
        return out

    def applicable(self, ctx):
        if len(ctx.hysteresis) < 2:
            return False
        typical = [np.median(np.abs(x)) for x in self._rates(ctx)]
        return max(typical) > 1.2 * min(typical)

    def signature(self, ctx, alpha):
        rates = self._rates(ctx)
        scale = max(np.max(np.abs(x)) for x in rates)
        cols = []
        for r in ctx.runs:
            cols.append(rates.pop(0)[:, None] / scale if r.kind == "hysteresis" else None)
        return regression_evidence(self.name, ctx.runs, cols, "residual proportional to the loading rate dτ/dt across loops at different rates")

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True}


def _harmonics(run, orders) -> np.ndarray:
    """cos kφ, sin kφ over the run's output angle, for each order k: (N, 2·len(orders))."""
    phi = run.output_angle_rad
    return np.concatenate([np.stack([np.cos(k * phi), np.sin(k * phi)], axis=1) for k in orders], axis=1)


def _project_out(y: np.ndarray, columns: np.ndarray) -> np.ndarray:
    columns = columns[:, np.any(columns != 0, axis=0)]
    if not columns.shape[1]:
        return y
    q, _ = np.linalg.qr(columns)
    return y - q @ (q.T @ y)


def _without_harmonics(run, orders):
    """``run`` with the harmonics of ``orders`` treated as nuisance and the noise re-estimated
    from the residual without them."""
    design = np.concatenate([run.design, _harmonics(run, orders)], axis=1)
    return replace(run.renoised(_project_out(run.residual, design)), design=design)


class KinematicError(Effect):
    name = "kinematic_error"
    growable = True
    signature_text = "peaks in the spectrum of the TE residual over output angle, at integer orders"
    extension_text = "harmonic terms a_k cos kφ + b_k sin kφ at the orders found"

    def applicable(self, ctx):
        return bool(ctx.te)

    def _present(self, ctx):
        kin = ctx.effects.get(self.name)
        if not kin:
            return set()
        return set(kin.get("orders") if isinstance(kin, dict) else kin)

    def signature(self, ctx, alpha):
        # Forward selection of orders: a strong order with a few samples per period passes for
        # noise in the variogram estimate (its sample-to-sample swings are large) and hides the
        # weaker ones, so each found order is removed and the noise re-estimated before the next.
        runs = ctx.te
        samples = min(len(r.residual) for r in runs)
        top = int(min(MAX_KINEMATIC_ORDER, max(2, samples // 4)))
        present = self._present(ctx)
        orders = [k for k in range(1, top + 1) if k not in present]
        if not orders:
            return Evidence(self.name, 0.0, 0, 0.0, 0.0, "no orders to search", {"orders_found": [], "orders_searched": top})
        threshold = np.log10(alpha / len(orders))  # Bonferroni over the orders searched
        found, views, spectrum = [], runs, None
        while len(found) < len(orders):
            per_order = {k: regression_evidence(self.name, views, [_harmonics(r, [k]) for r in views], "")
                         for k in orders if k not in found}
            if spectrum is None:
                spectrum = {str(k): round(ev.statistic, 2) for k, ev in per_order.items()}
            best_k, best = min(per_order.items(), key=lambda kv: kv[1].log10_p)
            if not (best.dof and best.log10_p < threshold):
                break
            found.append(best_k)
            views = [_without_harmonics(r, found) for r in runs]
        if not found:
            return Evidence(self.name, 0.0, 0, 0.0, 0.0,
                            f"no significant order in 1..{top} (strongest: order {best_k}, log10 p {best.log10_p:.1f})",
                            {"orders_found": [], "orders_searched": top})
        found = sorted(found)
        # the joint test of the found orders, against the noise left once they are removed
        clean = [r.renoised(_project_out(r.residual, np.concatenate([r.design, _harmonics(r, found)], axis=1))) for r in runs]
        ev = regression_evidence(self.name, clean, [_harmonics(r, found) for r in clean],
                                 f"TE residual periodic over output angle at orders {found}",
                                 {"orders_found": found, "orders_searched": top, "spectrum": spectrum})
        # the order search is a multiple test: report the Bonferroni-corrected tail
        return Evidence(ev.effect, ev.statistic, ev.dof, min(0.0, ev.log10_p + np.log10(len(orders))), ev.explained, ev.description, ev.details)

    def extend(self, effects, evidence, ctx):
        orders = sorted(self._present(ctx) | set(evidence.details.get("orders_found", [])))
        return {**effects, self.name: orders}


class SpeedDependence(Effect):
    name = "speed_dependence"
    signature_text = "TE residual level that changes with run speed (sign follows the direction)"
    extension_text = "viscous friction c_v|v| and a speed-dependent compliance"

    def _speeds(self, ctx):
        return sorted({round(r.speed_rad_s, 9) for r in ctx.te})

    def applicable(self, ctx):
        return len(self._speeds(ctx)) >= 2

    def signature(self, ctx, alpha):
        vmax = max(r.speed_rad_s for r in ctx.te)
        cols = []
        for r in ctx.runs:
            if r.kind != "transmission_error":
                cols.append(None)
                continue
            v = r.speed_rad_s / vmax
            n = len(r.residual)
            cols.append(np.stack([np.full(n, r.direction * v), np.full(n, r.direction * v**2)], axis=1))
        return regression_evidence(self.name, ctx.runs, cols, "TE residual level changes with speed (linear and quadratic in |v|)")

    def extend(self, effects, evidence, ctx):
        n_speeds = len(self._speeds(ctx))
        return {**effects, self.name: {"viscous": True, "compliance_order": 1 if n_speeds >= 3 else 0}}


class Asymmetry(Effect):
    name = "asymmetry"
    signature_text = "+ and − torque branches differ in slope (residual even in mesh torque, ∝ |τ|)"
    extension_text = "separate + and − compliance (C(τ)·(1 + α·tanh(τ/w)))"

    def signature(self, ctx, alpha):
        cols = [np.abs(_t(r, ctx))[:, None] for r in ctx.runs]
        return regression_evidence(self.name, ctx.runs, cols, "residual grows with |τ| the same way for both signs: + and − stiffness differ")

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True}


class ThermalDrift(Effect):
    name = "thermal_drift"
    growable = True  # linear first; a warm-up shape when the residual still bends over time
    signature_text = ("slow trend of the residual over time within runs, not explained by torque; once a linear "
                      "drift is in, the residual still bending over time (saturating exponentials)")
    extension_text = "a linear drift term per run, then a warm-up shape (saturating exponentials) per run"

    def _shape(self, ctx):
        drift = ctx.effects.get(self.name)
        return None if not drift else "linear" if drift in (True, "linear") else drift

    def applicable(self, ctx):
        return self._shape(ctx) != "warm_up"

    def signature(self, ctx, alpha):
        # one trend per run, tested jointly: run i's columns are non-zero on run i only
        n = len(ctx.runs)
        shape = self._shape(ctx)
        k = 1 if shape is None else len(WARM_UP_FRACTIONS)
        cols = []
        for i, r in enumerate(ctx.runs):
            span = max(float(r.time_s[-1] - r.time_s[0]), 1e-12)
            t = (r.time_s - r.time_s[0]) / span
            c = np.zeros((len(r.residual), n * k))
            if shape is None:
                c[:, i] = t - 0.5
            else:  # the fitted linear drift is in the run's design: only the bend is tested
                c[:, i * k:(i + 1) * k] = 1.0 - np.exp(-t[:, None] / np.asarray(WARM_UP_FRACTIONS)[None, :])
            cols.append(c)
        text = ("residual trends over time within runs (one slope per run)" if shape is None else
                "residual bends over time within runs beyond the linear drift (saturating exponentials: a warm-up)")
        return regression_evidence(self.name, ctx.runs, cols, text, {"shape": "linear" if shape is None else "warm_up"})

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True if self._shape(ctx) is None else "warm_up"}


class TorqueOffset(Effect):
    name = "torque_offset"
    signature_text = "loop centred off zero torque: residual ∝ the model's slope dθ/dτ"
    extension_text = "a torque-sensor offset"

    def applicable(self, ctx):
        return bool(ctx.hysteresis)

    def signature(self, ctx, alpha):
        cols = [(r.sensitivity * ctx.rated_torque_Nm)[:, None] if r.kind == "hysteresis" else None for r in ctx.runs]
        return regression_evidence(self.name, ctx.runs, cols, "residual proportional to the loop's local slope dθ/dτ: the loop is shifted in torque")

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True}


def _small_cycle_masks(ctx) -> list:
    """Per run: its samples of the smallest cycles (1) and the others (0), as the fit marked them;
    None for a run with no such samples (a TE run, a hysteresis run of one amplitude class)."""
    out = []
    for r, inp in zip(ctx.runs, ctx.map_result.problem.inputs):
        small = np.broadcast_to(np.asarray(inp.small_cycle, float), (len(r.residual),)) if r.kind == "hysteresis" else None
        out.append(small if small is not None and small.any() else None)
    return out


def play_crossing_shift(ctx: FitContext, masks) -> float | None:
    """By how much (N·m) the data's gap-crossing centre on the smallest cycles (the play ramps)
    lies off their centre on the larger cycles, both read off the data alone (:func:`gap_crossings`
    of the torque driving the model, the play ramps on their own samples): one gap crossed about
    two centres is the play ramps' torque zero moved by that much. None where either reading
    finds no crossing pair or the centres differ by less than the span the play ramps' crossing
    is read over."""
    small, large = [], []
    for r, mask in zip(ctx.runs, masks):
        if mask is None:
            continue
        rows = np.asarray(mask, bool)
        small.append(_Reading(r.drive_torque_Nm[rows], r.measured_angle_rad[rows]))
        large.append(_Reading(r.drive_torque_Nm[~rows], r.measured_angle_rad[~rows]))
    if not small:
        return None
    play, rest = gap_crossings(small), gap_crossings(large)
    shift = play.centre_Nm - rest.centre_Nm
    if not (np.isfinite(shift) and abs(shift) > play.span_Nm):
        return None
    return float(shift)


class PlayTorqueOffset(Effect):
    name = "play_torque_offset"
    signature_text = ("the play ramps' loop shifted in torque against the large cycles': residual ∝ dθ/dτ on the "
                      "smallest cycles' samples alone")
    extension_text = "a torque zero of the smallest cycles (the play ramps) of their own (a torque estimated from motor current)"

    def applicable(self, ctx):
        if ctx.effects.get(self.name):
            return False
        return any(mask is not None for mask in _small_cycle_masks(ctx))

    def signature(self, ctx, alpha):
        masks = _small_cycle_masks(ctx)
        cols = [None if mask is None else (r.sensitivity * ctx.rated_torque_Nm * mask)[:, None]
                for r, mask in zip(ctx.runs, masks)]
        slope = regression_evidence(self.name, ctx.runs, cols,
                                    "residual proportional to the loop's local slope dθ/dτ on the play ramps alone: "
                                    "the small cycles are shifted in torque against the large ones")
        # First order in δ_p, the slope's column lives where the fit's loop is steep: where the
        # gap is crossed in a jump the fit places at another torque than the data, it sees the
        # jump's flank and little else (independent simulator, play zero 0.8 N·m off: log10 p
        # −0.8). So the play ramps are also moved by the shift the data's crossings read — their
        # centre on the play ramps against the larger cycles' — and the residual tested along that
        # finite change and its derivative there (one-sided: the change must reduce the misfit),
        # the stronger of the two kept, Bonferroni-corrected for the two.
        shift = play_crossing_shift(ctx, masks)
        if shift is None:
            return slope
        problem = ctx.map_result.problem
        alt = dataclasses.replace(problem.model, play_torque_offset=True)
        moved = _score_test(
            ctx, self.name, alt, {self.name: shift},
            lambda pred, alt_pred, alt_jac: np.stack([alt_pred - pred, alt_jac[self.name]], axis=1),
            f"residual along the play ramps moved by {shift:+.3g} N·m in torque (where the data's crossings on them "
            "centre against the larger cycles') and its derivative there", {"play_torque_offset_Nm": shift})
        if not (moved.details.get("coefficients") and moved.details["coefficients"][0] > 0):
            moved = replace(moved, log10_p=0.0)
        best = min((slope, moved), key=lambda ev: ev.log10_p)
        return replace(best, log10_p=min(0.0, best.log10_p + float(np.log10(2))))

    def start_values(self, evidence):
        found = evidence.details.get("play_torque_offset_Nm")
        return {} if found is None else {self.name: found}

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True}


# --- friction and the gap: score tests against the fitted model ------------------------------------------
@eqx.filter_jit
def _alt_directions(problem, u, alt, extra: dict):
    """The prediction of the ``alt`` model at the fit ``u`` of ``problem`` plus ``extra``, and
    its Jacobian with respect to ``extra``."""
    values = problem.full_values(u)
    inputs = problem.corrected_inputs(u[:problem.n_nonlinear])
    alt_pred = alt.predict({**values, **extra}, inputs)
    alt_jac = jax.jacfwd(lambda ex: alt.predict({**values, **ex}, inputs))(extra)
    return alt_pred, alt_jac


def _directions(ctx: FitContext, alt, extra: dict):
    """At the fit: the prediction per run, its Jacobian with respect to every physics parameter
    of the fitted model (once per fit, shared by every candidate), the prediction of the ``alt``
    model at the same values plus ``extra`` and its Jacobian with respect to ``extra``."""
    pred, jac = ctx.physics_directions
    alt_pred, alt_jac = _alt_directions(ctx.map_result.problem, jnp.asarray(ctx.map_result.u), alt, extra)
    return pred, jac, alt_pred, alt_jac


def _columns(jac_run: dict) -> np.ndarray:
    """A run's Jacobian (name → (N,) or (N, size)) as an (N, k) matrix."""
    cols = [np.asarray(v, float).reshape(np.shape(v)[0], -1) for v in jac_run.values()]
    return np.concatenate(cols, axis=1) if cols else np.zeros((0, 0))


def _span(x: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """Well-conditioned columns spanning the non-negligible part of ``x``'s column space (each
    column scaled to unit norm first, so units do not decide what is negligible)."""
    norms = np.linalg.norm(x, axis=0)
    x = x[:, norms > 0] / norms[norms > 0]
    if not x.shape[1]:
        return x
    uu, sv, _ = np.linalg.svd(x, full_matrices=False)
    return uu[:, sv > rtol * sv[0]] * sv[sv > rtol * sv[0]]


def _score_test(ctx: FitContext, name: str, alt, extra: dict, columns, description: str, details=None,
                nuisance=None) -> Evidence:
    """Signature of a hysteresis-run extension (friction, gap lag) as a score test: ``columns(pred, alt_pred, alt_jac)``
    gives per run the first-order directions of the extension (N, k); they are tested on the
    hysteresis runs' whitened residuals after projecting out the run's linear terms and the
    fitted model's own physics directions (what a refit of the present parameters would absorb),
    and ``nuisance(run)`` ((N, k) per run) when given."""
    extra = {k: jnp.asarray(v, float) for k, v in extra.items()}
    pred, jac, alt_pred, alt_jac = _directions(ctx, alt, extra)
    views, cols = [], []
    for i, run in enumerate(ctx.runs):
        if run.kind != "hysteresis":
            views.append(run)
            cols.append(None)
            continue
        # spanned per run (not aligned across runs): the run's own nuisance columns
        own = _columns(jac[i])
        if nuisance is not None:
            own = np.concatenate([own, nuisance(run)], axis=1) if own.size else nuisance(run)
        views.append(replace(run, local_design=_span(own)))
        cols.append(columns(np.asarray(pred[i]), np.asarray(alt_pred[i]), {k: np.asarray(v) for k, v in alt_jac[i].items()}))
    return regression_evidence(name, views, cols, description, details)


def _with_friction(model, friction):
    return eqx.tree_at(lambda mm: mm.friction, model, friction)


#: break-away spread of the slip elements the distributed-friction signature compares with
SIGNATURE_SPREAD = 0.8


def replace_friction(friction, **changes):
    """``friction`` with its static fields changed."""
    if isinstance(friction, DahlFriction):
        fields = dict(initial_state=friction.initial_state, load_dependent=friction.load_dependent, load_lag=friction.load_lag,
                      load_memory=friction.load_memory)
        return DahlFriction(**{**fields, **changes})
    fields = dict(n_elements=friction.n_elements, initial_state=friction.initial_state, load_dependent=friction.load_dependent,
                  load_lag=friction.load_lag, load_memory=friction.load_memory)
    return MaxwellSlipFriction(**{**fields, **changes})


class LoadDependentFriction(Effect):
    name = "load_dependent_friction"
    signature_text = "loop width (flat span after a reversal) grows with the peak load; branches not parallel"
    extension_text = "friction level T_f + μ|τ| growing with the transmitted torque"

    def applicable(self, ctx):
        return bool(ctx.hysteresis) and not ctx.map_result.problem.model.friction.load_dependent

    def signature(self, ctx, alpha):
        # The score of μ at μ = 0: the prediction's derivative with respect to μ at the fitted
        # values — for Dahl friction −C'(τ_m)·|τ|·z, for slip elements the load each element
        # carried at its last slip — which is exactly what the missing μ leaves in the residual.
        fr = ctx.map_result.problem.model.friction
        alt = _with_friction(ctx.map_result.problem.model, replace_friction(fr, load_dependent=True))
        return _score_test(
            ctx, self.name, alt, {"friction_load_coefficient": 0.0},
            lambda pred, alt_pred, alt_jac: alt_jac["friction_load_coefficient"][:, None],
            "residual along the fitted model's derivative with respect to a load-dependent friction level μ|τ| "
            "(flat span after a reversal growing with the peak)")

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True}


class FrictionLoadLag(Effect):
    name = "friction_load_lag"
    rivals = ("friction_load_memory",)
    signature_text = ("the loop leaves a peak sooner and crosses the gap further from zero after a large cycle than a "
                      "friction level following the instantaneous load allows")
    extension_text = "the load-dependent friction level follows |τ| through a first-order lag T_L"

    def applicable(self, ctx):
        fr = ctx.map_result.problem.model.friction
        return bool(ctx.hysteresis) and fr.load_dependent and not fr.load_lag and not fr.load_memory

    def signature(self, ctx, alpha):
        # The score of T_L at T_L → 0, as for the gap lag: the prediction's derivative with
        # respect to the lag, μ·(−T_L·d|τ|/dt) through the friction level, tested against
        # everything a refit of the present parameters absorbs; evaluated at a lag far below
        # one sample step, where the lag is the identity to first order.
        problem = ctx.map_result.problem
        alt = _with_friction(problem.model, replace_friction(problem.model.friction, load_lag=True))
        return _lag_score_test(
            ctx, self.name, alt, "friction_load_lag_time",
            "residual along the fitted model's response to a friction level lagging the load (|τ| lagged by "
            "T_L → 0: −μ·T_L·d|τ|/dt in the level): the level is behind the load at a peak and still up after it")

    def rival_start_values(self, ctx):
        # the prior's centre: a tenth of the median ramp
        ramp = first_look_ramp_time_s(ctx.campaign)
        return {"friction_load_lag_time": 0.1 * ramp} if ramp else {}

    def extend(self, effects, evidence, ctx):
        return _load_level_with(effects, "lag")


#: the memory m at which the remembered-peak signature is evaluated once a load-dependent level is
#: in: far below any fitted memory, where the remembered peak is the instantaneous load to first
#: order in m
SIGNATURE_MEMORY = 1e-4
#: memories searched when no load dependence is in yet (the strongest kept, Bonferroni-corrected)
MEMORY_SHARES = (0.5, 0.8, 0.95)


class FrictionLoadMemory(Effect):
    name = "friction_load_memory"
    # at one loading rate a lag in time is a lag in torque travel: a level lagging the load and
    # one remembering its peak both stay up after a reversal (SYNTHETIC friction bench, a 33 s
    # lag: the memory's signature ranked first and its refit reached 1.15″ against the lag's
    # 1.03″), so whichever is added, the other is refitted in its place
    rivals = ("friction_load_lag",)
    signature_text = ("after a large cycle the loop stays flat longer and crosses the gap further from zero than after a "
                      "small one, at any loading rate: the friction level remembers the cycle's peak load")
    extension_text = "the friction level grows with the last peak of |τ|, let down by (1 − m) per N·m the load travels back (μ·L)"

    def applicable(self, ctx):
        fr = ctx.map_result.problem.model.friction
        return bool(ctx.hysteresis) and not fr.load_lag and not fr.load_memory

    def signature(self, ctx, alpha):
        problem = ctx.map_result.problem
        fr = problem.model.friction
        alt = _with_friction(problem.model, replace_friction(fr, load_dependent=True, load_memory=True))
        if fr.load_dependent:
            # The score of m at m → 0: the prediction's derivative with respect to the memory,
            # which through the level is μ times the torque travelled since the last peak of |τ|
            # while |τ| falls (zero while it rises): a level still up after each reversal in
            # proportion to how far the torque has come back — a function of the torque path,
            # not of time, where the lag's direction (−T_L·d|τ|/dt) scales with the rate.
            return _score_test(
                ctx, self.name, alt, {"friction_load_memory": SIGNATURE_MEMORY},
                lambda pred, alt_pred, alt_jac: alt_jac["friction_load_memory"][:, None],
                "residual along the fitted model's response to a friction level that remembers the last peak load "
                "(the peak let down by (1 − m)·|Δ|τ||, m → 0: μ·m times the torque travelled back since the peak)")
        # No load dependence yet: the score of μ at μ = 0 with the level growing with a remembered
        # peak, for m at fixed shares. A remembered peak keeps the level nearly constant over a
        # cycle, at the cycle's own amplitude: the instantaneous level's direction (|τ|) misses it
        # (SYNTHETIC friction bench, m 0.84, μ 0.045: the instantaneous level's refit earned
        # ΔELPD 14 ± 9 and nothing was added), so waiting for that step first would never reach
        # the memory. The strongest m is kept, its p-value Bonferroni-corrected for the search;
        # one-sided: friction cannot fall with the load.
        return _strongest_positive(self.name, [_score_test(
            ctx, self.name, alt, {"friction_load_coefficient": 0.0, "friction_load_memory": memory},
            lambda pred, alt_pred, alt_jac: alt_jac["friction_load_coefficient"][:, None],
            f"residual along the fitted model's derivative with respect to a friction level μ·L growing with the "
            f"last peak load L remembered with share m = {memory:g} (let down by {1 - memory:g}·|Δ|τ||): each cycle "
            "slides at the level its own peak set", {"memory": memory}) for memory in MEMORY_SHARES],
            "residual asks for a friction level falling with the remembered load, not growing: no memory explains it")

    def start_values(self, evidence):
        # from the base model the refit starts at the memory the signature found, not at m ≈ 0
        return {"friction_load_memory": evidence.details["memory"]} if "memory" in evidence.details else {}

    def rival_start_values(self, ctx):
        return {"friction_load_memory": MEMORY_SHARES[1]}

    def extend(self, effects, evidence, ctx):
        return _load_level_with(effects, "memory")


def _load_level_with(effects: dict, option: str) -> dict:
    """``effects`` with ``load_dependent_friction`` switched on and ``option`` (lag, memory) set."""
    level = effects.get("load_dependent_friction", True)
    return {**effects, "load_dependent_friction": {**(level if isinstance(level, dict) else {}), option: True}}


def _strongest_positive(name: str, searched: list[Evidence], none_text: str) -> Evidence:
    """Of a search's evidence, the strongest whose first coefficient is positive (a one-sided
    effect), its p-value Bonferroni-corrected for the ``len(searched)`` tried; no evidence
    (``none_text``) when none is."""
    positive = [ev for ev in searched if ev.details.get("coefficients") and ev.details["coefficients"][0] > 0]
    if not positive:
        return Evidence(name, 0.0, 0, 0.0, 0.0, none_text)
    best = min(positive, key=lambda ev: ev.log10_p)
    return replace(best, log10_p=min(0.0, best.log10_p + float(np.log10(len(searched)))))


def _lag_score_test(ctx: FitContext, name: str, alt, parameter: str, description: str) -> Evidence:
    """Score test of a first-order lag ``parameter`` of ``alt`` at a time constant far below one
    sample step, where the lag is the identity to first order: the prediction's derivative with
    respect to it is the direction the missing lag leaves in the residual."""
    steps = np.concatenate([np.diff(r.time_s) for r in ctx.hysteresis])
    tiny = 1e-4 * float(np.median(steps[steps > 0])) if np.any(steps > 0) else 1e-6
    return _score_test(ctx, name, alt, {parameter: tiny}, lambda pred, alt_pred, alt_jac: alt_jac[parameter][:, None],
                       description)


class DistributedFriction(Effect):
    name = "distributed_friction"
    signature_text = "rounded pre-sliding after reversals that one Dahl element cannot follow"
    extension_text = "Maxwell-slip elements with a log-normal break-away density (spread s)"

    def applicable(self, ctx):
        return bool(ctx.hysteresis) and isinstance(ctx.map_result.problem.model.friction, DahlFriction)

    def signature(self, ctx, alpha):
        # Non-nested alternative (a P test): the change of the prediction when the fitted Dahl
        # element is replaced by slip elements of the same level with break-away spread s, and
        # the slip model's derivatives in s and in its level T_f (the best slip model lies near,
        # not at, the Dahl fit's level) — each orthogonal to everything the Dahl parameters
        # (T_f, τ_d, start state, …) can already do.
        problem = ctx.map_result.problem
        fr = problem.model.friction
        alt = _with_friction(problem.model, MaxwellSlipFriction(
            n_elements=DEFAULT_FRICTION_ELEMENTS, initial_state=fr.initial_state, load_dependent=fr.load_dependent,
            load_lag=fr.load_lag, load_memory=fr.load_memory))
        level = float(problem.physics_values(jnp.asarray(ctx.map_result.u))["friction_torque"])
        return _score_test(
            ctx, self.name, alt, {"breakaway_spread": SIGNATURE_SPREAD, "friction_torque": level},
            lambda pred, alt_pred, alt_jac: np.stack(
                [alt_pred - pred, alt_jac["breakaway_spread"], alt_jac["friction_torque"] * level], axis=1),
            f"residual along the change from one Dahl element to {DEFAULT_FRICTION_ELEMENTS} slip elements "
            f"(break-away spread {SIGNATURE_SPREAD}) and the slip model's derivatives in spread and level: "
            "rounded pre-sliding")

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True}


class GapLag(Effect):
    name = "gap_lag"
    # at one loading rate a damped crossing and a held one both cross the gap late: on a gap held
    # to 20 N·m (SYNTHETIC friction bench) the lag's signature ranked first, and the held gap,
    # added after it, left both in the model; so whichever is added, the other is refitted in its place
    rivals = ("gap_hold",)
    signature_text = "gap crossed late: the fast twist change near zero torque trails the torque in time"
    extension_text = "a first-order lag T_g of the torque the gap sees behind the mesh torque (damped crossing)"

    def applicable(self, ctx):
        return bool(ctx.hysteresis) and ctx.map_result.problem.model.gap_lag is None

    def signature(self, ctx, alpha):
        # The score of T_g at T_g → 0: the prediction's derivative with respect to the lag, the
        # gap's response to the mesh-torque perturbation −T_g·dτ_m/dt, tested against everything
        # a refit of the present parameters absorbs. Evaluated at a lag far below one sample
        # step, where the lag is the identity to first order.
        problem = ctx.map_result.problem
        alt = eqx.tree_at(lambda mm: mm.gap_lag, problem.model, GapLagTerm(), is_leaf=lambda x: x is None)
        return _lag_score_test(
            ctx, self.name, alt, "gap_lag_time",
            "residual along the fitted model's response to a damped gap crossing (the gap at the mesh torque "
            "lagged by T_g → 0: −T_g·dτ_m/dt through the gap): the gap is crossed late")

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True}


#: hold torques the held-gap signature tries, as shares of the hysteresis runs' largest mesh torque
GAP_HOLD_SHARES = (0.025, 0.05, 0.1, 0.2, 0.4)


class GapHold(Effect):
    name = "gap_hold"
    rivals = ("gap_lag",)
    signature_text = "gap crossed beyond the friction's shift, at the same torque whatever the loop's peak or rate"
    extension_text = "a gap held by its own friction: crossed once the mesh torque exceeds ±T_h (a relay)"

    def applicable(self, ctx):
        # the smooth gap alone: a preloaded, stepped or no-load (closure) gap is another shape
        return bool(ctx.hysteresis) and type(ctx.map_result.problem.model.backlash) is SmoothBacklash

    def signature(self, ctx, alpha):
        # Non-nested alternative (a P test, as the slip elements'), searched over the hold
        # torque: for T_h at fixed shares of the largest mesh torque, the change of the
        # prediction when the smooth gap is held up to T_h and the held gap's derivative in T_h
        # there — the gap alone moved against the direction of loading, at the same torque
        # whatever the peak or rate (a friction level moves the spring too, a damped crossing
        # moves it by the rate). The strongest T_h is kept, its p-value Bonferroni-corrected for
        # the search. Tested beyond the compliance curvature's own columns (τ³, τ⁵): a held gap
        # lowers the loading branch on (0, T_h) and raises the unloading one on (−T_h, 0), whose
        # odd, single-valued part is what a curved spring leaves (SYNTHETIC effects bench: with a
        # stiffening spring and no hold the held gap ranked first and was added, ΔELPD 84 ± 34).
        # One-sided: a hold only moves the crossing later, so a T_h whose change enters the
        # residual with a negative coefficient (the data cross earlier than the model, as on the
        # measured split initial loop) is no evidence for it. The score at T_h → 0 sees only an
        # infinitesimal shift at the crossing: on a gap held at 34 N·m (SYNTHETIC friction bench)
        # it ranked fourth (log10 p −605), below a damped crossing's, and the held gap was never
        # refitted. The gap's state before the first sample is the friction's.
        problem = ctx.map_result.problem
        alt = eqx.tree_at(lambda mm: mm.backlash, problem.model, HeldGapBacklash())
        values = problem.physics_values(jnp.asarray(ctx.map_result.u))
        start = np.asarray(values["friction_start"], float) if "friction_start" in values else np.zeros(problem.model.n_hysteresis)
        peak = max(float(np.max(np.abs(r.mesh_torque_Nm))) for r in ctx.hysteresis)
        curvature = _curvature(ctx)
        evidence = []
        for share in GAP_HOLD_SHARES:
            hold = share * peak
            evidence.append(_score_test(
                ctx, self.name, alt, {"gap_hold_torque": hold, "gap_start": start},
                lambda pred, alt_pred, alt_jac: np.stack([alt_pred - pred, alt_jac["gap_hold_torque"] * hold], axis=1),
                f"residual along the change from the smooth gap to one held by its own friction up to ±{hold:.3g} N·m "
                "of mesh torque and the held gap's derivative in its hold torque: the gap crossed later along each "
                "branch, the loaded flanks not moved", {"hold_torque_Nm": hold}, nuisance=curvature))
        off = off_centre_crossing(ctx)
        if off is not None:
            # A band centred on a torque of its own, where the data's crossings read directly and
            # the fit's differ in their centre: a centred hold moves both crossings outward and
            # cannot place a pair whose centre lies off zero (SYNTHETIC friction bench, a band
            # held 27 N·m about +14.5 N·m: the centred holds' refit gained ΔELPD 95 ± 106 and the
            # trail stopped). Tried at the hold and centre the crossings read.
            wider, centre, span = off
            hold = max(wider, span)  # beyond the friction's own shift, which the fit draws already
            alt_off = eqx.tree_at(lambda mm: mm.backlash, problem.model, HeldGapBacklash(centred=False))
            evidence.append(_score_test(
                ctx, self.name, alt_off, {"gap_hold_torque": hold, "gap_centre_torque": centre, "gap_start": start},
                lambda pred, alt_pred, alt_jac: np.stack([alt_pred - pred, alt_jac["gap_hold_torque"] * hold,
                                                          alt_jac["gap_centre_torque"]], axis=1),
                f"residual along the change from the smooth gap to one held by its own friction up to ±{hold:.3g} N·m "
                f"about a mesh torque of {centre:+.3g} N·m (where the data cross the gap against the fit) and the held "
                "gap's derivatives in its hold and its centre: both crossings moved, the loaded flanks not",
                {"hold_torque_Nm": hold, "centre_Nm": centre}, nuisance=curvature))
        return _strongest_positive(self.name, evidence, "residual moves the gap crossing earlier, not later, than a "
                                   "smooth gap: no hold torque explains it")

    def rival_applicable(self, ctx):
        return self.applicable(ctx)  # the smooth gap alone is what a hold replaces

    def rival_start_values(self, ctx):
        # the hold torque its own signature points at on the fit the rival was added to (the
        # nested start alone stays at the smaller model's optimum, see start_values)
        return self.start_values(self.signature(ctx, alpha=1.0))

    def start_values(self, evidence):
        # the nested start holds the gap at T_h ≈ 0, where the relay is the smooth gap and the
        # hold's gradient lives at the crossing alone: on the measured split loop the refit from
        # there (and from the prior's starts) stayed at the smaller model's optimum (ΔELPD −2)
        return _held_gap_starts(evidence)

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: {"centred": False} if "centre_Nm" in evidence.details else True}


def _curvature(ctx):
    """Nuisance columns τ³, τ⁵ of a run's mesh torque (per rated torque): the compliance
    curvature's own directions, which the held gap's signatures are tested beyond."""
    return lambda run: np.stack([_t(run, ctx) ** 3, _t(run, ctx) ** 5], axis=1)


def _held_gap_starts(evidence) -> dict:
    """Start values (N·m) of a held gap's hold and centre where its signature found them."""
    found = {"hold_torque_Nm": "gap_hold_torque", "centre_Nm": "gap_centre_torque"}
    return {name: evidence.details[key] for key, name in found.items() if key in evidence.details}


@dataclass(frozen=True)
class _Reading:
    torque_Nm: np.ndarray
    angle_rad: np.ndarray


def off_centre_crossing(ctx: FitContext) -> tuple[float, float, float] | None:
    """Where the data cross the gap against the fit, both read off the hysteresis runs' large
    cycles (:func:`gap_crossings`, on the torque driving the model): (how much further apart the
    data's rising and falling crossings lie than the fit's, by how much their centre lies off the
    fit's, the torque span a crossing is read over), all in N·m. None when either reading finds
    no crossing pair or the centres differ by less than the span."""
    data = gap_crossings([_Reading(v.drive_torque_Nm, v.measured_angle_rad) for v in ctx.hysteresis])
    fit = gap_crossings([_Reading(v.drive_torque_Nm, v.measured_angle_rad - v.residual) for v in ctx.hysteresis])
    shift = data.centre_Nm - fit.centre_Nm
    if not (np.isfinite(shift) and abs(shift) > data.span_Nm):
        return None
    return float(data.half_width_Nm - fit.half_width_Nm), float(shift), float(data.span_Nm)


class GapCentre(Effect):
    name = "gap_centre"
    signature_text = ("held gap crossed about a torque off zero: going up later and going down earlier than a band "
                      "centred on zero torque, or the other way round")
    extension_text = "the held gap's band centred on a mesh torque c of its own: crossed at c ± T_h"

    def applicable(self, ctx):
        backlash = ctx.map_result.problem.model.backlash
        return bool(ctx.hysteresis) and isinstance(backlash, HeldGapBacklash) and backlash.centred

    def signature(self, ctx, alpha):
        # The score of c at c = 0 (nested: the centred band is c = 0): the prediction's
        # derivative with respect to the band's centre, which moves both crossings the same way
        # along the torque — the rising one later and the falling one earlier for c > 0 — where
        # a hold moves them apart and a torque offset moves the whole loop with them. Two-sided:
        # a centre of either sign is the effect. Tested beyond the curvature's τ³, τ⁵ as the hold
        # is: an even, single-valued part near zero is what a curved spring also leaves.
        # The relay's derivative lives at the fit's crossings alone: where the data cross a long
        # way off them the score sees little (SYNTHETIC friction bench, a band held 27 N·m about
        # +14.5 N·m declared centred: the fit held it ±41 N·m, placing the rising crossing and not
        # the falling one, and the score at c = 0 had log10 p −1.0), so the band moved to where the
        # data's crossings lie off the fit's is tried too, its hold changed by what they read (a P
        # test, one-sided), and the stronger kept, its p-value Bonferroni-corrected for the two.
        problem = ctx.map_result.problem
        alt = eqx.tree_at(lambda mm: mm.backlash, problem.model, HeldGapBacklash(
            initial_state=problem.model.backlash.initial_state, centred=False))
        curvature = _curvature(ctx)
        at_zero = _score_test(
            ctx, self.name, alt, {"gap_centre_torque": 0.0},
            lambda pred, alt_pred, alt_jac: alt_jac["gap_centre_torque"][:, None],
            "residual along the held gap's derivative with respect to the centre of its band: both crossings "
            "moved the same way along the torque, the loaded flanks not moved", nuisance=curvature)
        coefficients = at_zero.details.get("coefficients")
        if coefficients:  # the centre to first order (the column is the derivative per N·m of c)
            at_zero = replace(at_zero, details={**at_zero.details, "centre_Nm": float(coefficients[0])})
        off = off_centre_crossing(ctx)
        if off is None:
            return at_zero
        # the band moved and widened or narrowed by what the crossings read: a centred fit may
        # have placed one crossing with a longer hold (the other then lies twice the centre off)
        wider, centre, span = off
        hold = max(float(ctx.map_result.values["gap_hold_torque"]) + wider, span)
        moved = _score_test(
            ctx, self.name, alt, {"gap_centre_torque": centre, "gap_hold_torque": hold},
            lambda pred, alt_pred, alt_jac: np.stack([alt_pred - pred, alt_jac["gap_centre_torque"],
                                                      alt_jac["gap_hold_torque"] * hold], axis=1),
            f"residual along the change of the held gap's band to ±{hold:.3g} N·m about {centre:+.3g} N·m (where "
            "the data cross the gap against the fit) and its derivatives in centre and hold there: both crossings "
            "moved, the loaded flanks not", {"centre_Nm": centre, "hold_torque_Nm": hold}, nuisance=curvature)
        if not (moved.details.get("coefficients") and moved.details["coefficients"][0] > 0):
            moved = replace(moved, log10_p=0.0)
        best = min((at_zero, moved), key=lambda ev: ev.log10_p)
        return replace(best, log10_p=min(0.0, best.log10_p + float(np.log10(2))))

    def start_values(self, evidence):
        return _held_gap_starts(evidence)

    def extend(self, effects, evidence, ctx):
        hold = effects.get("gap_hold", True)
        return {**effects, "gap_hold": {**(hold if isinstance(hold, dict) else {}), "centred": False}}


#: half-spans of the relays' switches the relay-gap signature tries, as shares of the hysteresis
#: runs' largest mesh torque (the measured baseline loops: about 1.2, 2.5 and 5 N·m of 25 N·m)
GAP_RELAY_SPAN_SHARES = (0.05, 0.1, 0.2)


class GapRelays(Effect):
    """The gap crossed in held steps; ``from_smooth_gap``: tested on a smooth gap as well, not
    only once a held gap is in."""

    name = "gap_relays"
    nests = ("gap_hold",)
    signature_text = ("gap crossed in a staircase: steps at repeatable torques, at other torques going up than "
                      "coming down")
    extension_text = ("the gap crossed in held steps: relays whose up- and down-switches lie on a grid about a "
                      "centre, each with its share of the gap (a Preisach gap)")

    def __init__(self, from_smooth_gap: bool = False, max_span_share: float | None = RELAY_FLANK_SHARE):
        # max_span_share: the relays' half-span bound as a share of the hysteresis runs' largest
        # applied torque (None: unbounded). Bounded by default: unbounded, the relays added to
        # measured split loops spread their switches over 0.8 of the peak, drew the flanks'
        # hysteresis and took a gap of 2140′ against the data's 6.2′ play (docs/validation.md)
        self.from_smooth_gap = from_smooth_gap
        self.max_span_share = max_span_share

    def _bound_Nm(self, ctx) -> float | None:
        if self.max_span_share is None:
            return None
        return self.max_span_share * max(float(np.max(np.abs(v.drive_torque_Nm))) for v in ctx.hysteresis)

    def applicable(self, ctx):
        # The held gap is the one-relay case, and a preloaded or stepped gap is another shape.
        # Not from the smooth gap by default: its 28 shares draw any crossing shape, not only a
        # staircase. On the SYNTHETIC independent simulator's clean loop, whose gap is crossed
        # along a smoothstep in place of the tanh, a trail with them tried from the smooth gap
        # added them. On the measured baseline initial-pos1 loop that trail adds them first
        # (one held crossing alone earns too little there to be kept, so the default trail never
        # reaches them), but with a gap 2.4 times the play the data read (docs/validation.md)
        backlash = ctx.map_result.problem.model.backlash
        smooth = self.from_smooth_gap and type(backlash) is SmoothBacklash
        return bool(ctx.hysteresis) and (isinstance(backlash, HeldGapBacklash) or smooth)

    def signature(self, ctx, alpha):
        # Non-nested alternative (a P test, as the held gap's own): for a grid of relays about the
        # gap's centre, the change of the prediction from the current gap to the relays at even
        # shares and the derivatives in the K − 1 free logits, which together span every relay's
        # difference from the even shares. Searched over the grid's half-span, the strongest
        # kept, its p-value Bonferroni-corrected for the search. Tested beyond the curvature's
        # τ³, τ⁵ as the hold is. Two-sided: shares moved to the grid's relays may make a step
        # earlier or later. About the held gap's centre when one is fitted, else about the
        # data's own crossing centre (the large cycles', as the centre's prior), else zero.
        problem = ctx.map_result.problem
        current = problem.model.backlash
        bound = self._bound_Nm(ctx)
        relays = RelayGapBacklash(initial_state=getattr(current, "initial_state", 0.0),  # the smooth gap has no state
                                  max_span_Nm=bound)
        alt = eqx.tree_at(lambda mm: mm.backlash, problem.model, relays)
        values = problem.physics_values(jnp.asarray(ctx.map_result.u))
        start = np.asarray(values["friction_start"], float) if "friction_start" in values else np.zeros(problem.model.n_hysteresis)
        held = isinstance(current, HeldGapBacklash)
        centre = float(values.get("gap_centre_torque", 0.0))
        if not held:
            crossing = gap_crossings([_Reading(v.drive_torque_Nm, v.measured_angle_rad) for v in ctx.hysteresis]).centre_Nm
            centre = float(crossing) if np.isfinite(crossing) else 0.0
        found = {"hold_torque_Nm": float(values["gap_hold_torque"])} if held else {"centre_Nm": centre}
        peak = max(float(np.max(np.abs(r.mesh_torque_Nm))) for r in ctx.hysteresis)
        curvature = _curvature(ctx)
        evidence = []
        for share in GAP_RELAY_SPAN_SHARES:
            spread = relays.span_values(share * peak)  # inside the bound, if any
            span = float(relays.span_Nm(spread))
            extra = {"gap_centre_torque": centre, **spread, "gap_relay_logits": np.zeros(relays.n_relays - 1),
                     "gap_start": np.asarray(values["gap_start"], float) if "gap_start" in values else start}
            evidence.append(_score_test(
                ctx, self.name, alt, extra,
                lambda pred, alt_pred, alt_jac: np.concatenate(
                    [(alt_pred - pred)[:, None], alt_jac["gap_relay_logits"].reshape(alt_pred.shape[0], -1)], axis=1),
                f"residual along the change from the {'held' if held else 'smooth'} gap to relays whose switches lie "
                f"on a grid of {relays.n_thresholds} mesh torques over {centre:+.3g} ± {span:.3g} N·m, one share of the "
                "gap moved to each: the gap crossed in steps at other torques going up than coming down",
                {"relay_span_Nm": span, "max_span_Nm": bound, **found}, nuisance=curvature))
        best = min(evidence, key=lambda ev: ev.log10_p)
        return replace(best, log10_p=min(0.0, best.log10_p + float(np.log10(len(evidence)))))

    def start_values(self, evidence):
        # from a held gap: the fit it extends with its gap on the relay nearest the held one at
        # the span the signature found (from even shares, the nested start, the gap starts
        # smeared over the grid); from a smooth gap: even shares at that span about the centre
        # the signature was tested at
        if "relay_span_Nm" not in evidence.details:
            return {}
        relays = RelayGapBacklash(max_span_Nm=evidence.details.get("max_span_Nm"))
        span = evidence.details["relay_span_Nm"]
        if "hold_torque_Nm" not in evidence.details:
            return {**relays.span_values(span), "gap_centre_torque": evidence.details["centre_Nm"]}
        hold = evidence.details["hold_torque_Nm"]
        return {**relays.span_values(span),
                "gap_relay_logits": relays.logits_on(relays.nearest_relay(hold / span, -hold / span))}

    def extend(self, effects, evidence, ctx):
        bound = evidence.details.get("max_span_Nm")
        return {**{k: v for k, v in effects.items() if k != "gap_hold"},
                self.name: True if bound is None else {"max_span_Nm": float(bound)}}


class TemperatureDependence(Effect):
    name = "temperature_dependence"
    signature_text = "residual that changes with the runs' temperatures: TE level and loop slope move with it"
    extension_text = "compliance and friction level scaled by exp(α·ΔT) with the run's temperature"

    def applicable(self, ctx):
        temps = [ctx.campaign.run_temperature_C(r) for r in ctx.campaign.runs]
        return (None not in temps and len(set(temps)) >= 2
                and ctx.map_result.problem.model.temperature is None)

    def signature(self, ctx, alpha):
        # A score test at α = 0: the prediction's derivatives with respect to α_C and α_f at the
        # fitted values — ΔT times the compliance twist, ΔT times what the friction level does —
        # tested on every run against everything a refit of the present parameters can absorb.
        # Those are aligned across runs (one column per parameter, shared): a TE run's physics
        # directions are constants within the run, so spanned run by run they would remove the
        # very level shift between temperatures this test looks for.
        problem = ctx.map_result.problem
        term = TemperatureTerm(friction=self._friction(ctx))
        alt = eqx.tree_at(lambda mm: mm.temperature, problem.model, term, is_leaf=lambda x: x is None)
        extra = {p.name: jnp.asarray(0.0) for p in term.parameters()}
        pred, jac, alt_pred, alt_jac = _directions(ctx, alt, extra)
        views, cols = [], []
        for i, run in enumerate(ctx.runs):
            physics = _columns(jac[i])
            views.append(replace(run, design=np.concatenate([run.design, physics], axis=1) if physics.size else run.design))
            cols.append(np.stack([np.asarray(alt_jac[i][k], float) for k in extra], axis=1))
        temps = sorted({ctx.campaign.run_temperature_C(r) for r in ctx.campaign.runs})
        return regression_evidence(
            self.name, views, cols,
            f"residual along the model's derivatives with respect to a compliance and a friction level changing "
            f"with temperature (runs at {', '.join(f'{t:g}' for t in temps)} °C)",
            {"temperatures_C": temps, "reference_C": ctx.campaign.reference_temperature_C,
             "friction": self._friction(ctx)})

    @staticmethod
    def _friction(ctx) -> bool:
        """Whether the friction level's coefficient can be told from the compliance's."""
        return len(temperatures_resolving_friction(ctx.campaign)) >= 2

    def extend(self, effects, evidence, ctx):
        return {**effects, self.name: True if self._friction(ctx) else {"friction": False}}


CATALOG: tuple[Effect, ...] = (
    StiffnessNonlinearity(),
    RateDependence(),
    KinematicError(),
    SpeedDependence(),
    Asymmetry(),
    ThermalDrift(),
    TorqueOffset(),
    PlayTorqueOffset(),
    LoadDependentFriction(),
    FrictionLoadLag(),
    FrictionLoadMemory(),
    DistributedFriction(),
    TemperatureDependence(),
    GapLag(),
    GapHold(),
    GapCentre(),
    GapRelays(),
)
