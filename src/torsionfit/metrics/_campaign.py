"""Catalog metrics of a whole campaign: the `torsionfit metrics` JSON (DESIGN §5.2) and table."""

from ..io._campaign import Campaign, HysteresisRun, TransmissionErrorRun
from ._hysteresis import hysteresis_metrics
from ._te import te_metrics


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


def _run_torque(campaign: Campaign, run: HysteresisRun) -> float:
    """T_r for a hysteresis run: the rated torque, or the run's nominal peak load if lower."""
    rated = float(campaign.reducer.rated_torque_Nm)
    peak = getattr(run, "peak_torque_Nm", None)
    return rated if peak is None else min(rated, float(peak))


def campaign_metrics(
    campaign: Campaign,
    *,
    lost_motion_pct: float = 3.0,
    t1_Nm: float | None = None,
    t2_Nm: float | None = None,
    te_window_deg: float = 2.0,
) -> dict:
    """Catalog metrics of every run, as the `torsionfit metrics --json` document.

    Returns ``{"runs": [{"name", "kind", "metrics": {NAME: {"value", "unit"[, "note"]}}}]}``
    in manifest order, plain floats and strings only (JSON-serialisable). Hysteresis runs use
    :func:`hysteresis_metrics` at the reducer's rated torque (or at the run's nominal peak
    load ``peak_torque_Nm`` when that is lower); TE runs use :func:`te_metrics` against the
    no-load run of the same direction when there is one (:func:`reference_run_for`).
    Raises :class:`InputError` naming the run when a metric cannot be computed.
    """
    runs = []
    for run in campaign.runs:
        if isinstance(run, HysteresisRun):
            metrics = hysteresis_metrics(
                run,
                _run_torque(campaign, run),
                lost_motion_pct=lost_motion_pct,
                t1_Nm=t1_Nm,
                t2_Nm=t2_Nm,
            )
        elif isinstance(run, TransmissionErrorRun):
            metrics = te_metrics(
                run, reference_run_for(campaign, run), te_window_deg=te_window_deg
            )
        else:  # pragma: no cover - the io layer only makes these two kinds
            continue
        runs.append({"name": run.name, "kind": run.kind, "metrics": metrics})
    return {"runs": runs}


def format_metrics_table(result: dict) -> str:
    """A fixed-width terminal table of a :func:`campaign_metrics` result: one block per run,
    one line per metric with its value and unit (notes are in the JSON)."""
    blocks = []
    for run in result["runs"]:
        lines = [f"{run['name']} ({run['kind']})"]
        width = max((len(name) for name in run["metrics"]), default=0)
        for name, entry in run["metrics"].items():
            lines.append(f"  {name:<{width}}  {entry['value']:>14.6g}  {entry['unit']}")
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks) + "\n"
