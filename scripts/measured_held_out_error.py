"""Where the held-out error of the measured validation lies — REAL data
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), read from predictions saved outside
the repository, never copied into it.

The validation's held-out ramp (the last large ramp of each file) is split into the samples
at the **gap crossing** and the rest. On every branch of the ramp that crosses zero torque the
crossing is where the twist jumps furthest over one N·m of (running-median) torque, found in
the data and in the model's prediction apart; the crossing window is the torque span from
1.5 N·m before the earlier of the two to 1.5 N·m past the later. Per loop: the share of the
held-out samples in that window and the share of the squared error they carry, the RMSE in and
out of it, and the torque at which the data and the model cross (mean over the crossing
branches of each direction), and the Prandtl–Ishlinskii reference's RMSE in and out of the
same windows (refitted as the validation fits it, from the data file). A second table gives the
crossing torques of the data and the model on every large ramp, fitted and held out: where the
data cross (repeatably or not), where the model does, and how far apart on the fitted ramps.
A third splits the held-out error into each branch's mean offset (a ramp that walks as a
whole) and what is left (the shape), and reads the 90 % interval's coverage with those offsets
removed: is an interval too narrow because the ramp moved, or because its shape did?

    .venv/bin/python scripts/measured_validation.py --jobs 2 -o <folder> --save-predictions <predictions>
    .venv/bin/python scripts/measured_held_out_error.py <predictions> -o docs/measured/held-out-error.md
"""

import argparse
import sys
from pathlib import Path

import numpy as np

from torsionfit.metrics import branch_crossing

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "benchmarks"), str(ROOT / "scripts")]
ARCSEC = 180 / np.pi * 3600
JUMP_SPAN_NM = 1.0  # torque span over which a crossing's jump is read
WINDOW_MARGIN_NM = 1.5  # the crossing window reaches this far beyond both crossings
MIN_SIDE_NM = 3.0  # a crossing branch ends at least this far past zero torque
START_NM = 1.0  # … and starts no further than this past zero (a ramp may start near zero)
JUMP_RATIO = 2.0  # a crossing jumps this many times the branch's median move over the same span
PLAY_SPAN_NM = 0.5  # … over this span on the play ramps (±4 N·m: a branch eight N·m long)
NOISE_REPEATS = 20  # noise draws per posterior draw for the rebuilt 90 % interval
PLAY_REACH_NM = 3.5  # the play ramps cross a gap the large ramps cross within this torque (±4 N·m ramps)


def crossing(torque_filtered, angle_rad, direction: int, span_Nm: float = JUMP_SPAN_NM) -> tuple[float, float]:
    """(torque in N·m, jump in rad) where the twist of one monotone branch moves furthest in
    the branch's direction over ``span_Nm`` of torque; (nan, nan) if the branch is shorter or
    no move stands out (``JUMP_RATIO`` × the branch's median move over the same span)."""
    return branch_crossing(torque_filtered, angle_rad, direction, span_Nm, JUMP_RATIO)


def zero_crossing_branches(branch, torque_filtered):
    """(mask, direction ±1) of each monotone branch that starts within ``START_NM`` of zero torque
    (or before it) and ends ``MIN_SIDE_NM`` past it: the branches that cross the gap."""
    for k in np.unique(branch):
        sel = branch == k
        tf = torque_filtered[sel]
        d = 1 if tf[-1] > tf[0] else -1
        if d * tf[-1] > MIN_SIDE_NM and d * tf[0] < START_NM:
            yield sel, d


def crossing_windows(torque, angle_rad, prediction_rad, branch, torque_filtered):
    """Per zero-crossing branch: (direction, data crossing N·m, model crossing N·m, data jump rad,
    model jump rad, boolean mask of the branch's samples in the crossing window)."""
    out = []
    for sel, d in zero_crossing_branches(branch, torque_filtered):
        tf = torque_filtered[sel]
        c_data, j_data = crossing(tf, angle_rad[sel], d)
        c_model, j_model = crossing(tf, prediction_rad[sel], d)
        if not (np.isfinite(c_data) and np.isfinite(c_model)):
            continue
        lo = min(c_data, c_model) - WINDOW_MARGIN_NM
        hi = max(c_data, c_model) + WINDOW_MARGIN_NM
        mask = np.zeros(torque.size, bool)
        mask[np.nonzero(sel)[0]] = (tf >= lo) & (tf <= hi)
        out.append((d, c_data, c_model, j_data, j_model, mask))
    return out


def reference_block_means(unit: str, n: int) -> np.ndarray:
    """The PI reference's prediction of a unit's file (fitted without its last large ramp, as the
    validation fits it), in ``n`` block means as the saved predictions (rad)."""
    from measured_validation import _block, _data_path, reference_prediction as fitted
    from pi_reference import read_loop

    d = read_loop(_data_path(unit))
    pred = fitted(d)
    return _block(pred, d["angle_rad"].size // n, n)


def anatomy(saved: dict, reference_rad: np.ndarray | None = None) -> dict:
    """The held-out error of one saved prediction (``--save-predictions``), split at the
    crossing; with ``reference_rad`` (the reference's prediction, same samples) its error too."""
    from pi_reference import filter_torque
    from repeat_reference import branches

    nr = saved["test_nr"]
    held = nr == nr.max()
    tau, y = saved["torque_Nm"][held], saved["angle_rad"][held]
    pred = saved["prediction_rad"].mean(axis=0)[held]
    tf = filter_torque(tau)
    windows = crossing_windows(tau, y, pred, branches(tf), tf)
    at_crossing = np.zeros(tau.size, bool)
    for *_, mask in windows:
        at_crossing |= mask
    sq = ((y - pred) * ARCSEC) ** 2
    sq_ref = None if reference_rad is None else ((y - reference_rad[held]) * ARCSEC) ** 2

    def rms(m, e=sq):
        return float(np.sqrt(e[m].mean())) if m.any() else float("nan")

    def mean_of(direction, index):
        vals = [w[index] for w in windows if w[0] == direction]
        return float(np.mean(vals)) if vals else float("nan")

    return {
        "rmse_held_out_arcsec": rms(np.ones(tau.size, bool)),
        "crossing_branches": len(windows),
        "share_samples": float(at_crossing.mean()),
        "share_squared_error": float(sq[at_crossing].sum() / sq.sum()) if sq.sum() > 0 else float("nan"),
        "rmse_crossing_arcsec": rms(at_crossing),
        "rmse_elsewhere_arcsec": rms(~at_crossing),
        **({} if sq_ref is None else {
            "reference_rmse_held_out_arcsec": rms(np.ones(tau.size, bool), sq_ref),
            "reference_rmse_crossing_arcsec": rms(at_crossing, sq_ref),
            "reference_rmse_elsewhere_arcsec": rms(~at_crossing, sq_ref)}),
        **{f"crossing_{name}_{sgn}_Nm": mean_of(d, i)
           for d, sgn in ((1, "rising"), (-1, "falling")) for name, i in (("data", 1), ("model", 2))},
        **{f"jump_{name}_deg": float(np.rad2deg(np.mean([w[i] for w in windows]))) if windows else float("nan")
           for name, i in (("data", 3), ("model", 4))},
    }


def _ramp_crossings(saved: dict, pred: np.ndarray, ramp, span_Nm: float = JUMP_SPAN_NM):
    """(direction, data crossing N·m, model crossing N·m) of each zero-crossing branch of one
    ramp (``test_nr`` == ``ramp``); a crossing that does not stand out is nan."""
    from pi_reference import filter_torque
    from repeat_reference import branches

    on = saved["test_nr"] == ramp
    tf = filter_torque(saved["torque_Nm"][on])
    for sel, d in zero_crossing_branches(branches(tf), tf):
        yield (d, crossing(tf[sel], saved["angle_rad"][on][sel], d, span_Nm)[0],
               crossing(tf[sel], pred[on][sel], d, span_Nm)[0])


def ramp_crossings(saved: dict) -> dict:
    """Crossing torques (N·m) of the data and the model on every large ramp (``test_nr`` ≥ 100),
    fitted and held out: per direction the list over ramps, the crossing centre (the mean of the
    rising and falling medians over ramps), and the model's median offset from the data on the
    fitted ramps."""
    nr = saved["test_nr"]
    pred = saved["prediction_rad"].mean(axis=0)
    found = {(who, d): [] for who in ("data", "model") for d in (1, -1)}
    offsets = []
    for ramp in sorted(set(nr[nr >= 100].tolist())):
        for d, c_data, c_model in _ramp_crossings(saved, pred, ramp):
            found["data", d].append(c_data)
            found["model", d].append(c_model)
            if ramp != nr.max() and np.isfinite(c_data) and np.isfinite(c_model):
                offsets.append(c_model - c_data)

    def centre(who):
        rise, fall = (np.nanmedian(found[who, d]) if np.isfinite(found[who, d]).any() else np.nan for d in (1, -1))
        return float(0.5 * (rise + fall))

    return {
        **{f"{who}_{'rising' if d == 1 else 'falling'}_Nm": [float(x) for x in v] for (who, d), v in found.items()},
        "centre_data_Nm": centre("data"),
        "centre_model_Nm": centre("model"),
        "fitted_offset_model_minus_data_Nm": float(np.median(np.abs(offsets))) if offsets else float("nan"),
    }


def class_crossings(saved: dict) -> dict:
    """The crossing torques (N·m) of the play ramps (``test_nr`` < 100, read over
    ``PLAY_SPAN_NM``) and of the large ramps (over ``JUMP_SPAN_NM``), in the data and in the
    model: per class and direction the median over the crossing branches, and the centre (the
    mean of the rising and the falling median). A gap whose crossing is one property of the
    reducer crosses both classes about one centre."""
    nr = saved["test_nr"]
    pred = saved["prediction_rad"].mean(axis=0)
    out = {}
    for name, in_class, span in (("play", lambda r: r < 100, PLAY_SPAN_NM), ("large", lambda r: r >= 100, JUMP_SPAN_NM)):
        found = {(who, d): [] for who in ("data", "model") for d in (1, -1)}
        for ramp in sorted(r for r in set(nr.tolist()) if in_class(r)):
            for d, *at in _ramp_crossings(saved, pred, ramp, span):
                for who, c in zip(("data", "model"), at):
                    if np.isfinite(c):
                        found[who, d].append(c)
        for who in ("data", "model"):
            rise, fall = (float(np.median(found[who, d])) if found[who, d] else float("nan") for d in (1, -1))
            out[f"{name}_{who}"] = {"rising_Nm": rise, "falling_Nm": fall, "centre_Nm": 0.5 * (rise + fall)}
    return out


def offsets(saved: dict, seed: int = 0) -> dict:
    """The held-out ramp's error split into each monotone branch's mean offset and the rest, and
    the 90 % predictive interval's coverage of the data as they are and with those offsets
    removed (an oracle: the offsets are read off the held-out data). The interval is rebuilt as
    the validation builds it — each draw's prediction plus Gaussian noise at the saved marginal
    sd — with ``NOISE_REPEATS`` noise draws of its own per draw (``seed``)."""
    from pi_reference import filter_torque
    from repeat_reference import branches

    nr = saved["test_nr"]
    held = nr == nr.max()
    y = saved["angle_rad"][held]
    pred = np.asarray(saved["prediction_rad"], dtype=float)[:, held]
    sd = np.broadcast_to(saved["noise_marginal_rad"], saved["angle_rad"].shape)[held]
    residual = y - pred.mean(axis=0)
    label = branches(filter_torque(saved["torque_Nm"][held]))
    offset = np.zeros_like(residual)
    for k in np.unique(label):
        offset[label == k] = residual[label == k].mean()
    # several noise draws per parameter draw: a finer interval than the validation's (one each),
    # whose Monte-Carlo scatter can move a loop at the band's edge by a percent
    noise = np.random.default_rng(seed).standard_normal((NOISE_REPEATS, *pred.shape))
    noisy = (pred[None] + sd * noise).reshape(-1, pred.shape[1])
    lo, hi = np.quantile(noisy, [0.05, 0.95], axis=0)

    def inside(v):
        return float(np.mean((v >= lo) & (v <= hi)))

    return {"branches": int(np.unique(label).size),
            "offset_share_squared_error": float(np.sum(offset ** 2) / np.sum(residual ** 2)),
            "offset_rms_arcsec": float(np.sqrt(np.mean(offset ** 2)) * ARCSEC),
            "coverage90": inside(y), "coverage90_offsets_removed": inside(y - offset)}


def _signed(x: float, digits: int) -> str:
    """A signed number, or – for nan (a crossing not found)."""
    return f"{x:+.{digits}f}" if np.isfinite(x) else "–"


def markdown(rows: dict[str, dict]) -> str:
    lines = [
        "Where the held-out error lies (REAL measured data: JelmerV/Anti-Backlash-Cycloidal-Actuator, "
        "CC BY-SA 4.0; `scripts/measured_held_out_error.py` on the predictions the validation saves "
        "with `--save-predictions`). The held-out ramp split at its gap crossings: on each branch that "
        f"crosses zero torque, from {WINDOW_MARGIN_NM} N·m before the earlier of the data's and the model's "
        f"crossing (the largest jump of twist over {JUMP_SPAN_NM} N·m of running-median torque) to "
        f"{WINDOW_MARGIN_NM} N·m past the later. RMSE in arcsec (posterior mean prediction, raw samples); "
        "crossing torques in N·m, mean over the ramp's rising (− to +) and falling (+ to −) crossing "
        "branches; jump = the twist over the crossing's N·m, mean over branches.",
        "",
        "| unit | held-out RMSE model / reference | samples at the crossing | squared error at the crossing "
        "| RMSE at the crossing model / reference | RMSE elsewhere model / reference "
        "| crossing rising data / model | crossing falling data / model | jump data / model (deg) |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]

    def pair(r, key):
        ref = r.get(f"reference_{key}")
        return f"{r[key]:.0f}" + ("" if ref is None else f" / {ref:.0f}")

    for unit, r in rows.items():
        lines.append(
            f"| {unit} | {pair(r, 'rmse_held_out_arcsec')} | {100 * r['share_samples']:.0f} % "
            f"| {100 * r['share_squared_error']:.0f} % | {pair(r, 'rmse_crossing_arcsec')} "
            f"| {pair(r, 'rmse_elsewhere_arcsec')} "
            f"| {r['crossing_data_rising_Nm']:+.1f} / {r['crossing_model_rising_Nm']:+.1f} "
            f"| {r['crossing_data_falling_Nm']:+.1f} / {r['crossing_model_falling_Nm']:+.1f} "
            f"| {r['jump_data_deg']:.3f} / {r['jump_model_deg']:.3f} |")
    shares = np.array([r["share_squared_error"] for r in rows.values()])
    samples = np.array([r["share_samples"] for r in rows.values()])
    ratio = np.array([r["rmse_elsewhere_arcsec"] / r["rmse_held_out_arcsec"] for r in rows.values()])
    lines += ["", (
        f"On {len(rows)} loops the crossing windows hold {100 * samples.min():.0f}–{100 * samples.max():.0f} % "
        f"of the held-out samples (median {100 * np.median(samples):.0f} %) and carry "
        f"{100 * shares.min():.0f}–{100 * shares.max():.0f} % of the squared error (median "
        f"{100 * np.median(shares):.0f} %); away from them the RMSE is {100 * ratio.min():.0f}–"
        f"{100 * ratio.max():.0f} % of the whole ramp's (median {100 * np.median(ratio):.0f} %).")]
    jumps = np.array([r["jump_model_deg"] / r["jump_data_deg"] for r in rows.values()
                      if np.isfinite(r["jump_model_deg"] / r["jump_data_deg"])])
    if jumps.size:
        lines += ["", (
            f"The model's jump over the crossing's N·m against the data's: smaller on {np.sum(jumps < 1)} of "
            f"{jumps.size} loops (ratio {jumps.min():.2f}–{jumps.max():.2f}, median {np.median(jumps):.2f}).")]
    with_ref = [r for r in rows.values() if "reference_rmse_elsewhere_arcsec" in r]
    if with_ref:
        whole = np.array([r["rmse_held_out_arcsec"] / r["reference_rmse_held_out_arcsec"] for r in with_ref])
        away = np.array([r["rmse_elsewhere_arcsec"] / r["reference_rmse_elsewhere_arcsec"] for r in with_ref])
        at = np.array([r["rmse_crossing_arcsec"] / r["reference_rmse_crossing_arcsec"] for r in with_ref])
        lines += ["", (
            f"Model over reference, RMSE: the whole held-out ramp ≤ 0.8 on {np.sum(whole <= 0.8)} of {whole.size} "
            f"(median {np.median(whole):.2f}, worst {whole.max():.2f}); away from the crossings ≤ 0.8 on "
            f"{np.sum(away <= 0.8)} (median {np.median(away):.2f}, worst {away.max():.2f}); at the crossings "
            f"≤ 0.8 on {np.sum(at <= 0.8)} (median {np.median(at):.2f}, worst {at.max():.2f}).")]
    ramps = {unit: r["ramps"] for unit, r in rows.items() if "ramps" in r}
    if ramps:
        def listed(v):
            return ", ".join(_signed(x, 1) for x in v)

        lines += ["", (
            "Crossing torques on every large ramp of the file (the fitted ones, then the held-out one; N·m), found "
            "as above in the data and in the model's prediction; centre = the mean of the rising and the falling "
            "crossing (medians over ramps); offset = the median over the fitted ramps' crossings of |model − data|."),
            "", "| unit | rising data | rising model | falling data | falling model | centre data / model | offset on the fitted ramps |",
            "| --- | --- | --- | --- | --- | ---: | ---: |"]
        for unit, c in ramps.items():
            lines.append(
                f"| {unit} | {listed(c['data_rising_Nm'])} | {listed(c['model_rising_Nm'])} "
                f"| {listed(c['data_falling_Nm'])} | {listed(c['model_falling_Nm'])} "
                f"| {c['centre_data_Nm']:+.2f} / {c['centre_model_Nm']:+.2f} | {c['fitted_offset_model_minus_data_Nm']:.2f} |")
        cd = np.array([c["centre_data_Nm"] for c in ramps.values()])
        cm = np.array([c["centre_model_Nm"] for c in ramps.values()])
        off = np.array([c["fitted_offset_model_minus_data_Nm"] for c in ramps.values()])
        lines += ["", (
            f"The data's crossing centre lies more than 0.3 N·m off zero on {np.sum(np.abs(cd) > 0.3)} of {cd.size} "
            f"loops ({np.nanmin(cd):+.2f} to {np.nanmax(cd):+.2f} N·m), the model's on {np.sum(np.abs(cm) > 0.3)}; "
            f"on the fitted ramps the model crosses more than 0.5 N·m from the data (median) on {np.sum(off > 0.5)} "
            f"of {off.size} loops.")]
    classes = {unit: r["classes"] for unit, r in rows.items() if "classes" in r}
    if classes:
        def three(c):
            return f"{_signed(c['rising_Nm'], 1)} / {_signed(c['falling_Nm'], 1)} / {_signed(c['centre_Nm'], 2)}"

        lines += ["", (
            f"The play ramps against the large ramps: crossing torques (N·m) rising / falling / centre, medians "
            f"over each class's crossing branches (the play ramps' jump read over {PLAY_SPAN_NM} N·m, the large "
            f"ramps' over {JUMP_SPAN_NM} N·m; all ramps, fitted and held out); shift = the large ramps' centre "
            "minus the play ramps'."),
            "", "| unit | play ramps, data | play ramps, model | large ramps, data | large ramps, model "
            "| shift data / model |", "| --- | --- | --- | --- | --- | ---: |"]
        for unit, c in classes.items():
            shift = {who: c[f"large_{who}"]["centre_Nm"] - c[f"play_{who}"]["centre_Nm"] for who in ("data", "model")}
            lines.append(f"| {unit} | {three(c['play_data'])} | {three(c['play_model'])} | {three(c['large_data'])} "
                         f"| {three(c['large_model'])} | {_signed(shift['data'], 2)} / {_signed(shift['model'], 2)} |")
        # where the large ramps cross beyond the play ramps' reach (a held gap), what the play
        # ramps show at zero is not the same crossing
        same = {u: c for u, c in classes.items()
                if max(abs(c["large_data"]["rising_Nm"]), abs(c["large_data"]["falling_Nm"])) < PLAY_REACH_NM}
        shifts = np.array([c["large_data"]["centre_Nm"] - c["play_data"]["centre_Nm"] for c in same.values()])
        shifts = shifts[np.isfinite(shifts)]
        if shifts.size:
            lines += ["", (
                f"On the {shifts.size} loops whose large ramps cross within ±{PLAY_REACH_NM} N·m (a gap the ±4 N·m "
                f"play ramps cross too; on the others the play ramps stay inside the held gap's band) the data's "
                f"crossing centre moves from the play ramps to the large ramps by more than 0.5 N·m on "
                f"{np.sum(np.abs(shifts) > 0.5)} ({shifts.min():+.2f} to {shifts.max():+.2f} N·m; "
                f"{np.sum(shifts > 0.5)} up, {np.sum(shifts < -0.5)} down): one gap centre per loop cannot place "
                "both.")]
    split = {unit: r["offsets"] for unit, r in rows.items() if "offsets" in r}
    if split:
        lines += ["", (
            "The held-out error split into each monotone branch's mean offset (the branch moved as a whole) and the "
            "rest (its shape), and the 90 % interval's coverage with those offsets removed (read off the held-out "
            "data: an oracle, not a prediction). The interval is rebuilt from the saved draws with "
            f"{NOISE_REPEATS} noise draws each of its own (the validation's table draws as many with its own random "
            "numbers), so a loop at the band's edge may fall on the other side of it than in the table."),
            "", "| unit | branches | offset RMS (arcsec) | offsets' share of the squared error | coverage | "
            "coverage, offsets removed |", "| --- | ---: | ---: | ---: | ---: | ---: |"]
        for unit, o in split.items():
            lines.append(f"| {unit} | {o['branches']} | {o['offset_rms_arcsec']:.0f} "
                         f"| {100 * o['offset_share_squared_error']:.0f} % | {100 * o['coverage90']:.0f} % "
                         f"| {100 * o['coverage90_offsets_removed']:.0f} % |")
        cov = np.array([o["coverage90"] for o in split.values()])
        cov_off = np.array([o["coverage90_offsets_removed"] for o in split.values()])
        share = np.array([o["offset_share_squared_error"] for o in split.values()])
        band = (cov >= 0.8) & (cov <= 0.95)
        band_off = (cov_off >= 0.8) & (cov_off <= 0.95)
        below = cov < 0.8
        lines += ["", (
            f"The branches' offsets carry {100 * share.min():.0f}–{100 * share.max():.0f} % of the held-out squared "
            f"error (median {100 * np.median(share):.0f} %). The interval covers 80–95 % on {band.sum()} of "
            f"{cov.size} loops, with the offsets removed on {band_off.sum()}; of the {below.sum()} loops it covers "
            f"less than 80 %, removing the offsets brings {np.sum(below & band_off)} into the band"
            + (f" ({', '.join(f'{u} {100 * c:.0f} → {100 * o:.0f} %' for u, c, o, b in zip(split, cov, cov_off, below) if b)})"
               if below.any() else "") + ".")]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("predictions", type=Path, help="the folder of measured_validation.py --save-predictions")
    parser.add_argument("-o", "--output", type=Path, default=None, help="markdown file (default: print)")
    parser.add_argument("--no-reference", action="store_true",
                        help="the model's error alone (no data file needed)")
    args = parser.parse_args(argv)
    files = sorted(args.predictions.glob("*.npz"))
    if not files:
        print(f"{args.predictions}: no saved predictions (*.npz from measured_validation.py --save-predictions)",
              file=sys.stderr)
        return 2
    rows = {}
    for f in files:
        with np.load(f) as saved:
            missing = {"time_s", "torque_Nm", "angle_rad", "test_nr", "prediction_rad"} - set(saved.files)
            if missing:
                print(f"{f}: missing {sorted(missing)}; expected a file saved by measured_validation.py",
                      file=sys.stderr)
                return 2
            saved = dict(saved)
        n = saved["angle_rad"].size
        rows[f.stem] = anatomy(saved, None if args.no_reference else reference_block_means(f.stem, n))
        rows[f.stem]["ramps"] = ramp_crossings(saved)
        rows[f.stem]["classes"] = class_crossings(saved)
        if "noise_marginal_rad" in saved:
            rows[f.stem]["offsets"] = offsets(saved)
    text = markdown(rows)
    if args.output is None:
        print(text, end="")
    else:
        args.output.write_text(text)
        print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
