"""Data-only play and loading stiffness of the 21 measured cycloidal files — REAL data from
../shared/data/cycloidal-jv (JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0) — next to
the data authors' own numbers (the table of that folder's README).

Every file is read as ONE whole-file run (play ramps and stiffness ramps together, no
[runs.select]) from a manifest written to a temporary folder, without a rated torque: the
data-only metrics read their torque scale from the data. As the authors do, the three rotor
positions of a configuration are averaged: the play, and the + and − compliances separately.

    .venv/bin/python scripts/measured_metrics.py [-o docs/measured/metrics-vs-authors.md]
"""

import argparse
import csv
import gzip
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

import torsionfit  # noqa: F401
from torsionfit import InputError
from torsionfit.io import load_campaign
from torsionfit.fit._prior import cycle_friction_Nm
from torsionfit.metrics import campaign_metrics
from torsionfit.metrics._hysteresis import CLASS_METRICS, LOADING_FIT_TOP, grouped_cycles, loading_fit, play_of

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cycloidal-jv"
#: the goal: data-only play and stiffness_loading within this relative difference of the authors'
TOLERANCE = 0.10
#: the fractions of the peak at which the loading-slope fit is also ended, for the page's check
#: of where the authors end theirs (their text says "beyond the play", no end)
FIT_ENDS = (0.8, 0.9, 1.0)
CREDIT = (
    "REAL measured data from the public repository JelmerV/Anti-Backlash-Cycloidal-Actuator, "
    "licensed CC BY-SA 4.0; the numbers derived here carry the same licence."
)

MANIFEST = """label = "REAL MEASURED DATA (not synthetic): {folder}/{stem}, whole file; {credit}"

[reducer]
name = "jv-{folder}-{stem}"

[instrument]
encoder_resolution_arcsec = 19.775390625

[[runs]]
name = "{stem}"
kind = "hysteresis"
file = {file}

[runs.columns]
time = "TIME"
torque = "TORQUE"
angle = "POSITION"

[runs.units]
angle = "rev"
"""


def authors_numbers(readme: Path = DATA / "README.md") -> dict[tuple[str, str], dict]:
    """The authors' table of the data README: ``{(folder, state): {"play_deg", "compliance",
    "compliance_pos", "compliance_neg"}}`` (compliances in deg/N·m), in table order; a row that
    gives the mean compliance without its ``(+ / −)`` sides has None for them."""
    row = re.compile(
        r"^\|[^|]+\|\s*([\w-]+)\s*/\s*([\w-]+)\s*\|\s*([\d.]+)\s*\|\s*([\d.]+)\s*(?:\(([\d.]+)\s*/\s*([\d.]+)\)\s*)?\|"
    )
    out = {}
    for line in readme.read_text(encoding="utf-8").splitlines():
        m = row.match(line.strip())
        if m:
            play, mean = float(m[3]), float(m[4])
            pos, neg = (None, None) if m[5] is None else (float(m[5]), float(m[6]))
            out[(m[1], m[2])] = {"play_deg": play, "compliance": mean, "compliance_pos": pos, "compliance_neg": neg}
    return out


def fault_rows(path: Path) -> int:
    """Rows of a measured file whose controller ``FAULT`` code is not 0 (0 without the column:
    the data README's files carry it; on the 21 files here it is 0 throughout)."""
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, [])
        if "FAULT" not in header:
            return 0
        k = header.index("FAULT")
        return sum(1 for row in reader if len(row) > k and row[k].strip() not in ("", "0", "0.0"))


def fault_line(path: Path) -> str | None:
    """One stderr line naming a file with controller-fault rows, None without them."""
    n = fault_rows(path)
    return None if not n else (f"{path}: {n} row(s) with a controller FAULT code other than 0, read as they are "
                               f"(a manifest's [runs.select] FAULT = [0] leaves them out)")


def file_metrics(folder: str, stem: str, workdir: Path) -> dict:
    """``torsionfit metrics`` of one whole file: ``{"metrics", "notes"}`` of its one run."""
    path = DATA / folder / f"{stem}.csv.gz"
    if (line := fault_line(path)) is not None:
        print(line, file=sys.stderr)
    manifest = workdir / folder / stem / "campaign.toml"
    manifest.parent.mkdir(parents=True, exist_ok=True)
    manifest.write_text(
        MANIFEST.format(folder=folder, stem=stem, credit=CREDIT, file=f'"{path.as_posix()}"'), encoding="utf-8"
    )
    try:
        campaign = load_campaign(manifest)
    except InputError as err:  # the reader's checks (e.g. a reversed angle): named in the table's notes
        return {"name": stem, "kind": "hysteresis", "metrics": {}, "notes": {m: str(err) for m in CLASS_METRICS},
                "friction_Nm": None}
    (run,) = campaign_metrics(campaign)["runs"]
    (classes,) = grouped_cycles(campaign.hysteresis_runs)
    # the + and − compliances (deg/N·m) with the slope's fit ending at other fractions of the
    # peak: how much the authors' unstated end of the fit moves their number
    play = play_of(classes.smallest)
    run["compliance_by_fit_end"] = {}
    for top in FIT_ENDS:
        try:
            fit = loading_fit(classes.largest, play, name=stem, top=top)
        except InputError:
            continue
        run["compliance_by_fit_end"][top] = (float(np.degrees(fit.compliance_pos)), float(np.degrees(fit.compliance_neg)))
    # friction read off the loops (half the width in torque at the mid angle) of the smallest
    # and the largest cycles: equal where friction does not depend on the cycle's amplitude
    run["friction_Nm"] = {name: (float(np.max(np.abs(c.torque_Nm))), cycle_friction_Nm(c))
                          for name, c in (("smallest", classes.smallest), ("largest", classes.largest))}
    return run


def positions(folder: str, state: str, data: Path = DATA) -> list[str]:
    """The rotor positions measured for ``folder``/``state``: its files ``<state>-<position>.csv.gz``;
    SystemExit naming the folder when there is none (the README names a configuration the data lacks)."""
    found = sorted(p.name.removesuffix(".csv.gz").split("-", 1)[1] for p in (data / folder).glob(f"{state}-*.csv.gz"))
    if not found:
        raise SystemExit(f"{data / folder}: no file {state}-<position>.csv.gz for the README's configuration {folder} / {state}")
    return found


def measure(configurations) -> dict[tuple[str, str], dict]:
    """Per configuration: the runs of its positions (every file measured: pos1, pos5, pos6 here)
    and their averages (play in deg, + and − compliances in deg/N·m averaged separately, their
    mean and the loading stiffness 1/mean in N·m/arcmin)."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for folder, state in configurations:
            runs = {pos: file_metrics(folder, f"{state}-{pos}", Path(tmp)) for pos in positions(folder, state)}
            row = {"runs": runs, "notes": {}}
            for key, metric, scale in (
                ("play_deg", "play", 1 / 60.0),
                ("compliance_pos", "compliance_loading_pos", 1.0),
                ("compliance_neg", "compliance_loading_neg", 1.0),
            ):
                missing = [pos for pos, r in runs.items() if metric not in r["metrics"]]
                if missing:
                    row[key] = None
                    row["notes"][key] = "; ".join(f"{pos}: {runs[pos]['notes'].get(metric, '?')}" for pos in missing)
                    continue
                row[key] = sum(r["metrics"][metric]["value"] for r in runs.values()) * scale / len(runs)
            if row["compliance_pos"] is not None and row["compliance_neg"] is not None:
                row["compliance"] = 0.5 * (row["compliance_pos"] + row["compliance_neg"])
                row["stiffness_loading"] = 1.0 / (row["compliance"] * 60.0)  # N·m/deg → N·m/arcmin
            else:
                row["compliance"] = row["stiffness_loading"] = None
            out[(folder, state)] = row
    return out


def _rel(ours, theirs):
    return None if ours is None or theirs is None else ours / theirs - 1.0


def _pct(x):
    return "—" if x is None else f"{100 * x:+.1f} %"


def _num(x, fmt):
    return "—" if x is None else format(x, fmt)


def comparison(authors: dict, ours: dict) -> list[dict]:
    """One row per configuration: our values, theirs, relative differences, within TOLERANCE."""
    rows = []
    for key, a in authors.items():
        o = ours[key]
        d_play = _rel(o["play_deg"], a["play_deg"])
        # stiffness = 1/compliance: its relative difference is theirs/ours − 1 of the compliance
        d_stiff = None if o["compliance"] is None else a["compliance"] / o["compliance"] - 1.0
        rows.append({
            "configuration": f"{key[0]} / {key[1]}",
            "key": key,
            "ours": o,
            "authors": a,
            "d_play": d_play,
            "d_compliance": _rel(o["compliance"], a["compliance"]),
            "d_pos": _rel(o["compliance_pos"], a["compliance_pos"]),
            "d_neg": _rel(o["compliance_neg"], a["compliance_neg"]),
            "d_stiffness": d_stiff,
            "play_ok": d_play is not None and abs(d_play) <= TOLERANCE,
            "stiffness_ok": d_stiff is not None and abs(d_stiff) <= TOLERANCE,
        })
    return rows


def markdown(rows: list[dict]) -> str:
    lines = [
        "# Data-only play and loading stiffness against the data authors' numbers",
        "",
        CREDIT,
        "",
        f"Made by `scripts/measured_metrics.py`: each of the {sum(len(r['ours']['runs']) for r in rows)} files of "
        "`shared/data/cycloidal-jv` is one "
        "whole-file run (play ramps and stiffness ramps together), no rated torque given. "
        "`play` is the loop width at zero torque of the smallest cycles (the ±4 N·m play ramps); "
        "`stiffness_loading` is 1 / mean of the + and − loading-branch compliances of the largest "
        "cycles (the ±25 or ±40 N·m stiffness ramps), each a least-squares slope of angle on torque from "
        f"where the branch is past half the play (from the loop midpoint at zero torque) to {100 * LOADING_FIT_TOP:g} % "
        "of the peak. The positions (pos1, pos5 and pos6) are averaged as the authors do: the play, and the + and − "
        "compliances separately. Authors' numbers: the table of the data README. "
        f"Goal: within {100 * TOLERANCE:.0f} %.",
        "",
        "| configuration | play ours [°] | play authors [°] | Δ play | compliance ours [°/N·m] (+ / −) | "
        "compliance authors [°/N·m] (+ / −) | Δ compliance (Δ+ / Δ−) | stiffness_loading ours [N·m/arcmin] | "
        "authors' 1/compliance [N·m/arcmin] | Δ stiffness | within goal |",
        "| --- | ---: | ---: | ---: | --- | --- | --- | ---: | ---: | ---: | --- |",
    ]
    for r in rows:
        o, a = r["ours"], r["authors"]
        ok = "play " + ("yes" if r["play_ok"] else "NO") + ", stiffness " + ("yes" if r["stiffness_ok"] else "NO")
        lines.append(
            f"| {r['configuration']} | {_num(o['play_deg'], '.3f')} | {a['play_deg']:.3f} | {_pct(r['d_play'])} | "
            f"{_num(o['compliance'], '.4f')} ({_num(o['compliance_pos'], '.4f')} / {_num(o['compliance_neg'], '.4f')}) | "
            f"{a['compliance']:.3f} ({_num(a['compliance_pos'], '.3f')} / {_num(a['compliance_neg'], '.3f')}) | "
            f"{_pct(r['d_compliance'])} ({_pct(r['d_pos'])} / {_pct(r['d_neg'])}) | "
            f"{_num(o['stiffness_loading'], '.4f')} | {1 / (60 * a['compliance']):.4f} | {_pct(r['d_stiffness'])} | {ok} |"
        )
    lines += [
        "",
        "Per file (whole-file runs; play in °, compliances in °/N·m):",
        "",
        "| file | play | compliance + | compliance − | stiffness_loading [N·m/arcmin] | amplitude classes | "
        "friction at the mid angle, smallest / largest cycles [N·m] |",
        "| --- | ---: | ---: | ---: | ---: | --- | --- |",
    ]
    for r in rows:
        folder, state = r["key"]
        for pos, run in r["ours"]["runs"].items():
            m = run["metrics"]

            def get(name, scale=1.0, fmt=".4f"):
                return _num(m[name]["value"] * scale, fmt) if name in m else "—"

            classes = re.search(r"amplitude classes in the run: ([^;)]*N·m)", m.get("play", {}).get("note", ""))
            fr = run["friction_Nm"]
            friction = "—" if fr is None else (f"{fr['smallest'][1]:.2f} (±{fr['smallest'][0]:.0f}) / "
                                               f"{fr['largest'][1]:.2f} (±{fr['largest'][0]:.0f})")
            lines.append(
                f"| {folder}/{state}-{pos} | {get('play', 1 / 60, '.3f')} | {get('compliance_loading_pos')} | "
                f"{get('compliance_loading_neg')} | {get('stiffness_loading')} | {classes[1] if classes else '—'} | "
                f"{friction} |"
            )
    notes = [(r["configuration"], k, v) for r in rows for k, v in r["ours"]["notes"].items()]
    if notes:
        lines += ["", "Not computed:", ""] + [f"- {c}, {k}: {v}" for c, k, v in notes]
    lines += [
        "",
        "Friction at the mid angle: half the loop's width in torque where each branch passes the angle "
        "midway between the branches at zero torque (with a gap and a spring in series, friction is "
        "what shifts the branches apart in torque), of the smallest and of the largest cycles, their "
        "torque amplitude in brackets. Where the two agree, the friction the loop shows does not depend on "
        "the cycle's amplitude. A level that grows with the instantaneous torque does not make them differ "
        "once both cycles slide through; a broad density of break-away levels does (the small cycles slide "
        "on the weak elements only), and so would a level that remembers the last peak load.",
    ]
    lines += ["", fit_end_text(rows)]
    missed = [r["configuration"] for r in rows if not (r["play_ok"] and r["stiffness_ok"])]
    lines += [
        "",
        (f"All {len(rows)} configurations are within the goal." if not missed
         else "Outside the goal: " + ", ".join(missed) + "."),
    ]
    return "\n".join(lines) + "\n"


def fit_end_deltas(rows: list[dict], top: float) -> np.ndarray | None:
    """|relative difference| of our + and − compliances (positions averaged) from the authors',
    the slope's fit ended at ``top`` × the peak: two per configuration (None if a file has no fit)."""
    out = []
    for r in rows:
        runs = r["ours"]["runs"].values()
        sides = [run.get("compliance_by_fit_end", {}).get(top) for run in runs]
        if any(s is None for s in sides) or r["authors"]["compliance_pos"] is None:
            return None
        for k, name in ((0, "compliance_pos"), (1, "compliance_neg")):
            out.append(abs(np.mean([s[k] for s in sides]) / r["authors"][name] - 1.0))
    return np.asarray(out)


def fit_end_text(rows: list[dict]) -> str:
    """Where the loading-slope fit ends, against the authors' + and − compliances."""
    parts = []
    for top in FIT_ENDS:
        d = fit_end_deltas(rows, top)
        if d is not None:
            parts.append(f"at {100 * top:g} % of the peak: median {100 * np.median(d):.1f} %, worst {100 * d.max():.1f} %")
    return (
        "Where the slope's fit ends: the authors' text says \"beyond the play\" and names no end. The |difference| "
        f"of our + and − compliances (positions averaged, {2 * len(rows)} sides) from theirs, the fit ended "
        + "; ".join(parts) + f". The metrics end it at {100 * LOADING_FIT_TOP:g} % of the peak (the peak of the "
        "resampled branch: a torque plateau at a saturating bench's peak is one grid point)."
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=None, help="also write the Markdown table here")
    args = parser.parse_args(argv)
    if not DATA.is_dir():
        print(f"{DATA} is absent: nothing to compare")
        return 0
    authors = authors_numbers()
    text = markdown(comparison(authors, measure(authors)))
    print(text, end="")
    if args.output is not None:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(text, encoding="utf-8")
        print(f"wrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
