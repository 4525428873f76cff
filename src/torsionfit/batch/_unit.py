"""One unit of a batch: where it comes from and goes (``UnitTask``), its problem, the files it
leaves in ``OUT/<unit>/`` and its row. ``batch_row.json`` is written last: a unit whose row file
is there, says done, was made with the same settings and whose outputs are all present is
complete, and a re-run skips it."""

import json
import os
from dataclasses import dataclass
from pathlib import Path

from .._errors import error_line
from ..fit import check_fittable
from ..fit._contraction import prior_dominated_named
from ..io import load_campaign
from ..report import finish_fit, prepare_fit, write_fit
from ._options import BatchOptions

ROW_FILE = "batch_row.json"
DONE, ERROR = "done", "error"


@dataclass(frozen=True)
class UnitTask:
    """A unit: its name (folder under the batch's input, "." for the input itself), its
    manifest and its output folder."""

    unit: str
    manifest: Path
    out_dir: Path


def error_row(task: UnitTask, err: BaseException, options: BatchOptions) -> dict:
    row = {"unit": task.unit, "status": ERROR, "reason": error_line(err), "campaign": str(task.manifest),
           "sampler": options.sampler_of(task.unit)}
    if options.spec is not None:
        row["decision"] = ERROR
    return row


def prepare_unit(task: UnitTask, options: BatchOptions):
    """(campaign, decimated campaign, model, problem) of the unit; InputError on bad input."""
    campaign = load_campaign(task.manifest)
    check_fittable(campaign)  # e.g. no [reducer].rated_torque_Nm: one line, not a TypeError
    return (campaign,) + prepare_fit(campaign, options.fit_options_of(task.unit))


def _metric_columns(doc: dict) -> dict:
    out = {}
    for name, m in doc["metrics"].items():
        out[f"{name} [{m['unit']}]"] = m["mean"]
        out[f"{name} sd"] = m["sd"]
    return out


def finish_unit(task: UnitTask, prepared, map_result, options: BatchOptions, shape: str, sample_result=None) -> dict:
    """Posterior, metrics and (with a spec) the decision of one unit from its MAP (and its emcee
    run, when made already); writes its outputs and returns its row."""
    campaign, fitted, model, problem = prepared
    fit_options = options.fit_options_of(task.unit)
    fit = finish_fit(fitted, fit_options, model, problem, map_result, options.seed, sample_result)
    out = Path(task.out_dir)
    doc = write_fit(fit, out, command=options.command)
    d = doc["diagnostics"]
    row = {"unit": task.unit, "status": DONE, "sampler": d["sampler"], "converged": d["converged"],
           "map_converged": d["map_converged"], "reason": d.get("reason", ""), "shape": shape,
           "campaign": str(task.manifest), "label": doc.get("label"),
           "rmse_max [arcsec]": max(v["value"] for v in doc["rmse"].values()),
           # the reducer's parameters this unit's runs leave at their prior (fit/_contraction.py)
           "prior_dominated": ", ".join(prior_dominated_named(d["prior_dominated"], problem))}
    if options.figures:
        from ..plots import write_fit_figures

        write_fit_figures(fit, out / "figures")
    if options.spec is not None:
        from ..accept import accept_campaign, write_accept

        result = accept_campaign(campaign, options.spec, fit_options, seed=options.seed, fit=fit)
        acc = write_accept(result, out, figures=options.figures, command=options.command)
        row.update({k: acc[k] for k in ("decision", "p_conform", "consumer_risk", "producer_risk")})
        row["reason"] = acc["reason"]
        row.update({f"p_conform[{r['name']}]": r["p_conform"] for r in acc["requirements"]})
    row.update(_metric_columns(doc))
    return row


def write_row(task: UnitTask, row: dict, options: BatchOptions) -> None:
    """``OUT/<unit>/batch_row.json`` (row and settings), written atomically, last."""
    out = Path(task.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / (ROW_FILE + ".tmp")
    tmp.write_text(json.dumps({"settings": options.settings_of(task.unit), "row": row}, indent=2))
    os.replace(tmp, out / ROW_FILE)


def clear_row(task: UnitTask) -> None:
    """Remove the unit's row file (before the unit is done again: a row file found after a worker
    process died is then this run's)."""
    (Path(task.out_dir) / ROW_FILE).unlink(missing_ok=True)


def _row_file(task: UnitTask) -> dict:
    """The unit's row file ({"settings", "row"}); {} when missing or unreadable."""
    try:
        stored = json.loads((Path(task.out_dir) / ROW_FILE).read_text())
    except (OSError, ValueError):
        return {}
    return stored if isinstance(stored, dict) else {}


def written_row(task: UnitTask) -> dict | None:
    """The row in the unit's row file, whatever its status; None without one."""
    return _row_file(task).get("row")


def stored_row(task: UnitTask, options: BatchOptions) -> dict | None:
    """The stored row of a complete unit done with these settings, else None."""
    out = Path(task.out_dir)
    stored = _row_file(task)
    row = stored.get("row", {})
    needed = ["fit.json"] + (["accept.json"] if options.spec is not None else [])
    if options.sampler_of(task.unit) == "emcee":
        needed.append("posterior.nc")
    complete = (row.get("status") == DONE and stored.get("settings") == options.settings_of(task.unit)
                and all((out / name).is_file() for name in needed))
    return row if complete else None
