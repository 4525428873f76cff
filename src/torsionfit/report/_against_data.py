"""Does the model draw what the data read directly? The metrics both can read.

``play`` and ``stiffness_loading`` (with the two loading compliances) are read off the data
alone (``torsionfit.metrics``: the smallest cycles' loop width at zero torque, the largest
cycles' loading branches) and off the fitted model's noise-free prediction of the same record,
with the same definitions (``report/_record.py``). The data's reading carries a standard error
from the scatter of its cycles (``metrics.class_readings``).

A fit whose 95 % HDI misses the data's own reading by more than two of those standard errors
does not draw that feature of the loop: its interval is narrower than its error. On measured
loops of printed cycloidal reducers that is common (the validation's table counts the loops).
Such a metric is flagged in
``fit.json`` and in the summary, and the data's reading is the one to report — a model that is
confidently wrong says so.
"""

from .._errors import InputError
from ..metrics._hysteresis import Reading, class_readings, cycle_se, play_cycles, play_of
from ..units import from_si
from ._record import record_classes

#: the class metrics (model and data), in the model metrics' units
UNITS = {"play": "arcmin", "stiffness_loading": "Nm/arcmin", "compliance_loading_pos": "deg/Nm",
         "compliance_loading_neg": "deg/Nm"}

#: a reading off the model's HDI by more than this many of its standard errors is a miss
TOLERANCE_SE = 2.0


def _in_units(name: str, value: float, se: float | None) -> tuple[float, float | None]:
    """A class reading (SI) in the unit of the model's metric of the same name."""
    if name == "play":
        f = from_si(1.0, "angle", "arcmin")
        return value * f, None if se is None else se * f
    if name == "stiffness_loading":  # 1 / compliance: its s.e. to first order
        f = from_si(1.0, "stiffness", "Nm/arcmin")
        return f / value, None if se is None else f * se / value**2
    f = from_si(1.0, "angle", "deg")
    return value * f, None if se is None else se * f


def data_readings(campaign) -> dict[str, dict]:
    """``{metric: {"value", "se", "unit", "run"}}`` in the model metrics' units: the class
    metrics read off the data where the model reads them (``report/_record.py``: the smallest
    cycles for the play, the largest for the loading slope), each with its standard error from
    the scatter of its cycles (None with a single cycle). Empty when the campaign has no
    cycles to read, or no loading slope (then ``play`` alone)."""
    classes = record_classes(campaign)
    if classes is None:
        return {}
    try:
        if classes.loading_note is not None:  # the stiffness ramps form no loop: the play alone
            raise InputError(classes.loading_note)
        readings = class_readings(classes.small, classes.large, name=classes.large_run.name)
    except InputError:  # no loading slope to read: the data-only metrics' notes say why
        readings = {"play": Reading(play_of(classes.small), cycle_se(play_cycles(classes.small)))}
    readings["stiffness_loading"] = readings.pop("compliance_loading", None)
    if classes.play_note is not None:  # the play ramps form no loop: the width read is not the play
        readings.pop("play", None)
    out = {}
    for name, unit in UNITS.items():
        if readings.get(name) is not None:
            value, se = _in_units(name, readings[name].value, readings[name].se)
            out[name] = {"value": value, "se": se, "unit": unit,
                         "run": classes.small_run.name if name == "play" else classes.large_run.name}
    return out


def against_data(metrics: dict, readings: dict) -> list[str]:
    """Add ``"data"`` (the reading, and ``"within"``: whether the model's 95 % HDI holds it to
    within :data:`TOLERANCE_SE` of its standard errors; None, not judged, when no run has two
    cycles to give a standard error) to each entry of ``metrics`` (fit.json's) that the data
    read too; return the names whose HDI misses."""
    off = []
    for name, reading in readings.items():
        entry = metrics.get(name)
        if entry is None or entry.get("unit") != reading["unit"]:
            continue
        lo, hi = entry["hdi95"]
        if reading["se"] is None:  # one cycle: nothing says how far its reading may scatter
            entry["data"] = {**reading, "within": None}
            continue
        slack = TOLERANCE_SE * reading["se"]
        within = bool(lo - slack <= reading["value"] <= hi + slack)
        entry["data"] = {**reading, "within": within}
        if not within:
            off.append(name)
    return off


def unreadable_notes(read_shares: dict[str, float], campaign, n_draws: int) -> dict[str, str]:
    """Why each metric of ``read_shares`` is left out of a fit: its definition reads a value off
    the model on that share (< ½) of the ``n_draws`` draws (fit.json's
    ``diagnostics.metrics_not_computed``); for a class metric, the data-only reading's own
    reason where it fails too (read once for all of them)."""
    data = None
    if set(read_shares) & set(UNITS):
        classes = record_classes(campaign)
        if classes is None:
            data = "; the data has no hysteresis run whose cycles can be grouped"
        else:
            try:
                class_readings(classes.small, classes.large, name=classes.large_run.name)
                data = " (the data-only reading has one: torsionfit metrics)"
            except InputError as err:
                data = f"; the data-only reading fails as well: {err}"
    notes = {}
    for name, share in read_shares.items():
        notes[name] = (f"its definition reads no value off the model on any of {n_draws} draws" if share == 0 else
                       f"its definition reads a value off the model on only {100 * share:.0f} % of {n_draws} draws")
        if name in UNITS:
            notes[name] += data
    return notes


def off_data_note(metrics: dict, off: list[str]) -> str:
    """One line for the summary and fit.json: which metrics the model does not draw."""
    parts = []
    for name in off:
        e, d = metrics[name], metrics[name]["data"]
        se = "" if d["se"] is None else f" ± {d['se']:.3g}"
        parts.append(f"{name} {e['mean']:.4g} (95 % HDI {e['hdi95'][0]:.4g}–{e['hdi95'][1]:.4g}) against the data's "
                     f"{d['value']:.4g}{se} {d['unit']}")
    return ("the model does not draw what the data read directly — " + "; ".join(parts)
            + ": its interval is narrower than its error; report the data's reading (torsionfit metrics)")
