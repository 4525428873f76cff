"""Catalog metrics of a whole campaign: the `torsionfit metrics` JSON (DESIGN §5.2) and table."""

from ..io._campaign import Campaign, HysteresisRun, TransmissionErrorRun
from .._errors import InputError
from ._hysteresis import hysteresis_run_metrics
from ._te import te_metrics

#: the TE metrics named in a note when a TE run cannot be read
TE_METRICS = ("kd", "kt")


def reference_run_for(
    campaign: Campaign, run: TransmissionErrorRun
) -> TransmissionErrorRun | None:
    """The no-load TE run (``torque_Nm == 0``) in the same direction as ``run``, or None.

    With several, the one nearest in speed (then the first in the manifest). A no-load run
    has no reference: it is the reference.
    """
    if run.torque_Nm == 0:
        return None
    candidates = [
        r
        for r in campaign.te_runs
        if r is not run and r.torque_Nm == 0 and r.direction == run.direction
    ]
    if not candidates:
        return None
    return min(candidates, key=lambda r: abs(float(r.speed_rpm) - float(run.speed_rpm)))


def campaign_metrics(
    campaign: Campaign,
    *,
    lost_motion_pct: float = 3.0,
    t1_Nm: float | None = None,
    t2_Nm: float | None = None,
    te_window_deg: float = 2.0,
) -> dict:
    """Catalog metrics of every run, as the `torsionfit metrics --json` document.

    Returns ``{"runs": [{"name", "kind", "metrics": {NAME: {"value", "unit"[, "note"]}},
    "notes": {NAME: text}, "reading": [text]}]}`` in manifest order (``reading``: the run's
    reading notes — a column negated or unwrapped, a pad dropped), plain floats and strings only
    (JSON-serialisable). Every metric that can be computed is in ``metrics`` with a finite
    value; one that cannot is left out of ``metrics`` and its reason is in ``notes`` (so a
    consumer reading ``metrics[NAME]["value"]`` never meets a null).

    Hysteresis runs use :func:`hysteresis_run_metrics`: the loop metrics at the reducer's rated
    torque (or at the run's nominal peak load ``peak_torque_Nm`` when that is lower or no rated
    torque is given; with neither, at the loop's own peak), ``play`` from the smallest cycles
    and ``stiffness_loading`` from the largest. TE runs use :func:`te_metrics` against the
    no-load run of the same direction when there is one (:func:`reference_run_for`).
    """
    rated = campaign.reducer.rated_torque_Nm
    runs = []
    for run in campaign.runs:
        notes: dict[str, str] = {}
        if isinstance(run, HysteresisRun):
            metrics, notes = hysteresis_run_metrics(
                run, rated, lost_motion_pct=lost_motion_pct, t1_Nm=t1_Nm, t2_Nm=t2_Nm
            )
        elif isinstance(run, TransmissionErrorRun):
            try:
                metrics = te_metrics(
                    run, reference_run_for(campaign, run), te_window_deg=te_window_deg
                )
            except InputError as err:
                metrics, notes = {}, {name: str(err) for name in TE_METRICS}
        else:  # pragma: no cover - the io layer only makes these two kinds
            continue
        runs.append({"name": run.name, "kind": run.kind, "metrics": metrics, "notes": notes,
                     "reading": list(run.notes)})
    return {"runs": runs}


def format_metrics_table(result: dict) -> str:
    """A fixed-width terminal table of a :func:`campaign_metrics` result: one block per run,
    its reading notes (``read:``: a column negated or unwrapped, a pad dropped), one line per
    metric with its value and unit (the metrics' notes are in the JSON), then one line per
    metric that could not be computed, with its reason."""
    blocks = []
    for run in result["runs"]:
        lines = [f"{run['name']} ({run['kind']})"] + [f"  read: {note}" for note in run.get("reading", ())]
        notes = run.get("notes", {})
        width = max((len(name) for name in [*run["metrics"], *notes]), default=0)
        for name, entry in run["metrics"].items():
            lines.append(f"  {name:<{width}}  {entry['value']:>14.6g}  {entry['unit']}")
        for name, note in notes.items():
            lines.append(f"  {name:<{width}}  {'—':>14}  not computed: {note}")
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks) + "\n"
