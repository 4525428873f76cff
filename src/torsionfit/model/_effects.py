"""Switching model extensions on by name (the effects catalog's names, DESIGN §3)."""

import math

from .._errors import InputError
from ._backlash import (DEFAULT_GAP_STEPS, DEFAULT_GAP_THRESHOLDS, ClosedGapBacklash, FrictionClosureBacklash, HeldGapBacklash, PreloadedBacklash,
                        RelayGapBacklash, ResidualPlayBacklash, SmoothBacklash, SteppedBacklash)
from ._campaign_model import CampaignModel
from ._compliance import AsymmetricCompliance, LinearCompliance, PowerLawCompliance, PreloadedCompliance, ThreeSegmentCompliance
from ._creep import Creep
from ._drift import SHAPES as DRIFT_SHAPES
from ._friction import LOAD_GROWTH, DahlFriction, MaxwellSlipFriction
from ._gap_lag import GapLag
from ._kinematic import KinematicHarmonics
from ._series import SeriesCompliance
from ._speed import SpeedDependence
from ._temperature import TemperatureDependence


def model_with_effects(run_kinds, effects: dict, rated_torque_Nm: float, scan="auto", free_friction_start: bool = False,
                       fitted: bool = False, te_loads_Nm=None) -> CampaignModel:
    """The base model plus the extensions named in ``effects`` (the catalog names of
    DESIGN §3: ``stiffness_nonlinearity``, ``rate_dependence``, ``kinematic_error``,
    ``speed_dependence``, ``asymmetry``, ``thermal_drift``, ``torque_offset``, ``play_torque_offset``,
    ``load_dependent_friction``, ``distributed_friction``, ``temperature_dependence``, ``gap_preload``, ``gap_hold``, ``gap_relays``, ``gap_lag``,
    ``series_compliance``, ``preload_stiffening``), as a bench file's ``[effects]``
    table or a user's switches give them. ``fitted``: the model a fit estimates, whose gap
    is :class:`FrictionClosureBacklash` when no run is a hysteresis run (the same curve, with the
    share of the gap closed at no load in place of a closing torque the data cannot see), or
    :class:`ClosedGapBacklash` when ``te_loads_Nm`` (the TE runs' loads) has no run at no load
    (nothing then sees the gap open); a simulation keeps :class:`SmoothBacklash`."""
    compliance = LinearCompliance()
    nonlin = effects.get("stiffness_nonlinearity")
    if nonlin in (True, "three_segment"):
        compliance = ThreeSegmentCompliance()
    elif nonlin == "power_law":
        compliance = PowerLawCompliance(reference_torque_Nm=float(rated_torque_Nm))
    elif nonlin not in (None, False):
        raise InputError(f"[effects].stiffness_nonlinearity: expected 'three_segment' or 'power_law', got {nonlin!r}")
    # the preloaded second path changes the spring itself; an asymmetry scales the result
    preloaded = _switched("preload_stiffening", effects.get("preload_stiffening", False), lambda: PreloadedCompliance(compliance))
    compliance = compliance if preloaded is None else preloaded
    asym = effects.get("asymmetry")
    if asym:
        width = asym.get("switch_width_Nm", 0.05 * rated_torque_Nm) if isinstance(asym, dict) else 0.05 * rated_torque_Nm
        compliance = AsymmetricCompliance(compliance, switch_width_Nm=float(width))
    kin = effects.get("kinematic_error")
    kinematic = None
    if kin:
        orders = kin.get("orders") if isinstance(kin, dict) else kin
        if not isinstance(orders, list) or not all(isinstance(o, int) and o > 0 for o in orders):
            raise InputError(f"[effects].kinematic_error: expected a list of positive integer orders, got {kin!r}")
        kinematic = KinematicHarmonics(orders=tuple(orders))
    drift = effects.get("thermal_drift")
    drift_shape = "linear" if drift in (None, False, True) else drift
    if drift_shape not in DRIFT_SHAPES:
        raise InputError(f"[effects].thermal_drift: expected true, 'linear' or 'warm_up', got {drift!r}")
    sp = effects.get("speed_dependence")
    speed = None
    if sp:
        opts = sp if isinstance(sp, dict) else {}
        speed = SpeedDependence(viscous=bool(opts.get("viscous", True)), compliance_order=int(opts.get("compliance_order", 0)))
    closed = fitted and "hysteresis" not in tuple(run_kinds)
    preload = _gap_preload(effects.get("gap_preload", False))
    if preload is not None and closed:
        raise InputError("[effects].gap_preload: needs a hysteresis run (a TE run sees the gap closed or at its no-load share, never the preload)")
    steps = _gap_steps(effects.get("gap_steps", False))
    if steps is not None and (preload is not None or closed):
        raise InputError("[effects].gap_steps: needs a hysteresis run and cannot be combined with gap_preload")
    hold = _gap_hold(effects.get("gap_hold", False))
    if hold is not None and (closed or preload is not None or steps is not None):
        raise InputError("[effects].gap_hold: needs a hysteresis run and cannot be combined with gap_preload or gap_steps")
    relays = _gap_relays(effects.get("gap_relays", False))
    if relays is not None and (closed or preload is not None or steps is not None or hold is not None):
        raise InputError("[effects].gap_relays: needs a hysteresis run and cannot be combined with gap_preload, gap_steps or gap_hold")
    if closed:
        loaded = te_loads_Nm is not None and len(te_loads_Nm) > 0 and min(abs(float(t)) for t in te_loads_Nm) > 0
        backlash = ClosedGapBacklash() if loaded else FrictionClosureBacklash()
    else:
        backlash = next((b for b in (preload, steps, hold, relays) if b is not None), SmoothBacklash())
    return CampaignModel(
        backlash=backlash,
        temperature=_temperature(effects.get("temperature_dependence", False)),
        free_friction_start=free_friction_start,
        friction=_friction(effects),
        run_kinds=tuple(run_kinds),
        compliance=compliance,
        creep=Creep() if effects.get("rate_dependence") else None,
        gap_lag=_switched("gap_lag", effects.get("gap_lag", False), GapLag),
        series=_switched("series_compliance", effects.get("series_compliance", False), SeriesCompliance),
        kinematic=kinematic,
        speed=speed,
        drift=bool(drift),
        drift_shape=drift_shape,
        torque_offset=bool(effects.get("torque_offset")),
        play_torque_offset=_plain("play_torque_offset", effects.get("play_torque_offset", False)),
        scan=scan,
    )


def _plain(name: str, value) -> bool:
    """An effect with no options: true or false."""
    if isinstance(value, bool):
        return value
    raise InputError(f"[effects].{name}: expected true or false, got {value!r}")


def _flagged(name: str, value, key: str, default: bool, make):
    """An effect switched on by ``true`` (``make(default)``) or by a table with one boolean
    option ``{key = …}`` (``make(option)``); None for ``false``."""
    if value is False or value is None:
        return None
    if value is True:
        return make(default)
    if isinstance(value, dict) and set(value) <= {key} and isinstance(value.get(key, default), bool):
        return make(value.get(key, default))
    raise InputError(f"[effects].{name}: expected true, false or {{{key} = {str(not default).lower()}}}, got {value!r}")


def _gap_preload(value):
    """``gap_preload``: false, true (:class:`PreloadedBacklash`) or {residual_play = true}
    (:class:`ResidualPlayBacklash`: a small share of the gap crossed at zero torque besides)."""
    return _flagged("gap_preload", value, "residual_play", False,
                    lambda residual: ResidualPlayBacklash() if residual else PreloadedBacklash())


def _gap_hold(value):
    """``gap_hold``: false, true (:class:`HeldGapBacklash`, its band centred on zero mesh torque)
    or {centred = false} (the band centred on a fitted torque of its own)."""
    return _flagged("gap_hold", value, "centred", True, lambda centred: HeldGapBacklash(centred=centred))


def _gap_steps(value):
    """``gap_steps``: false, or {steps = N, span_Nm = S} (a gap taken up in N steps spread over
    ±S N·m of mesh torque; N defaults to 7, S has no default: it is the unit's, not ours). An odd N
    puts a step at zero torque, so the plain centred gap is the case of all shares on it."""
    if value is False or value is None:
        return None
    steps = value.get("steps", DEFAULT_GAP_STEPS) if isinstance(value, dict) else None
    span = value.get("span_Nm") if isinstance(value, dict) else None
    if not (isinstance(value, dict) and set(value) <= {"steps", "span_Nm"}
            and isinstance(steps, int) and not isinstance(steps, bool) and steps >= 2
            and isinstance(span, (int, float)) and not isinstance(span, bool) and span > 0):
        raise InputError(f"[effects].gap_steps: expected {{steps = N, span_Nm = S}} with N ≥ 2 (default {DEFAULT_GAP_STEPS}) and S > 0 N·m, got {value!r}")
    return SteppedBacklash(n_steps=steps, span_Nm=float(span))


def _gap_relays(value):
    """``gap_relays``: false, true or {thresholds = G, max_span_Nm = S} (:class:`RelayGapBacklash`:
    a gap crossed in held steps whose up- and down-switches lie on G mesh torques spread over a
    fitted span about a fitted centre; G defaults to 7; the span is at most S N·m when S is
    given, unbounded otherwise)."""
    if value is False or value is None:
        return None
    n = value.get("thresholds", DEFAULT_GAP_THRESHOLDS) if isinstance(value, dict) else DEFAULT_GAP_THRESHOLDS
    bound = value.get("max_span_Nm") if isinstance(value, dict) else None
    if not (value is True or (isinstance(value, dict) and set(value) <= {"thresholds", "max_span_Nm"}
                              and isinstance(n, int) and not isinstance(n, bool) and n >= 2
                              and (bound is None or (isinstance(bound, (int, float)) and not isinstance(bound, bool)
                                                     and math.isfinite(bound) and bound > 0)))):
        raise InputError(f"[effects].gap_relays: expected true, false or {{thresholds = G, max_span_Nm = S}} with G ≥ 2 "
                         f"(default {DEFAULT_GAP_THRESHOLDS}) and S > 0 N·m (default: unbounded), got {value!r}")
    return RelayGapBacklash(n_thresholds=n, max_span_Nm=None if bound is None else float(bound))


#: Maxwell-slip elements of ``distributed_friction = true``
DEFAULT_FRICTION_ELEMENTS = 6


def _friction(effects: dict):
    """Dahl friction, or Maxwell-slip elements (``distributed_friction``); either with a
    level growing with the load (``load_dependent_friction``: the instantaneous load, a lagged
    one, or a remembered peak)."""
    load = effects.get("load_dependent_friction", False)
    lag, memory, growth = False, False, "proportional"
    if (isinstance(load, dict) and set(load) <= {"lag", "memory", "growth"}
            and isinstance(load.get("lag", False), bool) and isinstance(load.get("memory", False), bool)
            and load.get("growth", growth) in LOAD_GROWTH):
        load, lag, memory, growth = True, load.get("lag", False), load.get("memory", False), load.get("growth", growth)
    if not isinstance(load, bool):
        raise InputError(f"[effects].load_dependent_friction: expected true, false or a table {{lag = true}} or "
                         f"{{memory = true}} (or both), with growth = \"common\" (growth one of {', '.join(LOAD_GROWTH)}), got {load!r}")
    dist = effects.get("distributed_friction", False)
    if dist is False or dist is None:
        if growth != "proportional":
            raise InputError(f"[effects].load_dependent_friction: growth = {growth!r} needs distributed_friction "
                             f"(one Dahl element has no spread of levels to keep)")
        return DahlFriction(load_dependent=load, load_lag=lag, load_memory=memory)
    n = dist.get("elements", DEFAULT_FRICTION_ELEMENTS) if isinstance(dist, dict) else DEFAULT_FRICTION_ELEMENTS if dist is True else dist
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 64:
        raise InputError(f"[effects].distributed_friction: expected true or {{elements = N}} with 1 ≤ N ≤ 64, got {dist!r}")
    return MaxwellSlipFriction(n_elements=n, load_dependent=load, load_lag=lag, load_memory=memory, load_growth=growth)


def _temperature(value):
    """``temperature_dependence``: true (compliance and friction level) or {friction = false}."""
    if value is False or value is None:
        return None
    if value is True:
        return TemperatureDependence()
    if isinstance(value, dict) and set(value) <= {"friction"} and isinstance(value.get("friction", True), bool):
        return TemperatureDependence(friction=value.get("friction", True))
    raise InputError(f"[effects].temperature_dependence: expected true, false or {{friction = false}}, got {value!r}")


def _switched(name: str, value, component):
    """``component()`` for an effect switched on by ``true``, None for ``false``."""
    return component() if _plain(name, value) else None
