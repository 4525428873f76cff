"""What the play ramps give back after each peak, per side: data against the model — REAL data
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), read from the predictions
``scripts/measured_validation.py --save-predictions <folder>`` saves (they hold the data and
stay outside the repository).

On the play ramps (``test_nr`` < 100, ±4 N·m) each half-cycle runs from one peak to the other.
Read here, per side and as the median over a file's half-cycles: the twist between the end of
the + peak and the unloading branch's zero torque (the *+ drop*), and between the end of the −
peak and the loading branch's zero torque (the *− rise*). The play read at zero torque is the
loop's width there, so whatever the model gives back wrongly after a peak goes into its play:
the model's play minus the data's is about its peak-to-peak twist minus the data's plus
(data − model) of the + drop and of the − rise. The model's values are the median (and the 5–95 % range) over the saved posterior
predictive draws.

    .venv/bin/python scripts/measured_play_edges.py <predictions folder> [-o page.md]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

#: play ramps: test_nr below this
PLAY_TEST_NR = 100
#: the torque is smoothed over this many samples (block means of 16 raw samples) to find the peaks
SMOOTH_SAMPLES = 7
#: a peak: the smoothed torque beyond this share of the ramps' extreme
PEAK_SHARE = 0.85


def give_back_deg(torque_Nm: np.ndarray, twist_deg: np.ndarray) -> tuple[float, float, float, int]:
    """(+ drop, − rise, peak-to-peak twist, half-cycles read): the median twist (°) given back
    between the end of each peak and the returning branch's zero torque, and the median twist at
    the + peaks' ends less the − peaks'."""
    smooth = np.convolve(torque_Nm, np.ones(SMOOTH_SAMPLES) / SMOOTH_SAMPLES, mode="same")
    side = np.where(smooth > PEAK_SHARE * smooth.max(), 1, np.where(smooth < PEAK_SHARE * smooth.min(), -1, 0))
    at_peak = np.flatnonzero(side != 0)
    drop, rise, ends = [], [], {1: [], -1: []}
    for i, j in zip(at_peak[:-1], at_peak[1:]):
        if side[i] == side[j] or j - i < 3:  # within a peak, or a peak's noisy edge
            continue
        zero = i + int(np.argmin(np.abs(smooth[i:j])))
        end = twist_deg[max(0, i - 2): i + 1].mean()
        ends[side[i]].append(end)
        (drop if side[i] == 1 else rise).append(abs(end - twist_deg[zero - 1: zero + 2].mean()))
    median = lambda v: float(np.median(v)) if v else float("nan")  # noqa: E731
    return median(drop), median(rise), median(ends[1]) - median(ends[-1]), len(drop) + len(rise)


def loop_row(path: Path) -> dict:
    """Data and model (median and 5–95 % over the draws) of one saved prediction file."""
    with np.load(path) as saved:
        play = saved["test_nr"] < PLAY_TEST_NR
        if not play.any():
            raise SystemExit(f"{path}: no play ramps (test_nr < {PLAY_TEST_NR})")
        torque = saved["torque_Nm"][play]
        data = give_back_deg(torque, np.degrees(saved["angle_rad"][play]))
        draws = np.array([give_back_deg(torque, np.degrees(p[play]))[:3] for p in saved["prediction_rad"]])
    return {"unit": path.stem, "data": data[:2], "peak_to_peak": data[2], "half_cycles": data[3],
            "model": np.median(draws[:, :2], axis=0), "model_range": np.percentile(draws[:, :2], [5, 95], axis=0),
            "model_peak_to_peak": float(np.median(draws[:, 2]))}


def markdown(rows: list[dict]) -> str:
    outside = [r["unit"] for r in rows
               if any(not lo <= d <= hi for d, lo, hi in zip(r["data"], *r["model_range"]))]
    lines = ["What the play ramps give back after each peak (REAL data: JelmerV/Anti-Backlash-Cycloidal-Actuator, "
             "CC BY-SA 4.0), data against the model's posterior predictive draws: "
             f"the data's value outside the model's 5–95 % range on one side or both on {len(outside)} of {len(rows)} loops.",
             "", "Made by `scripts/measured_play_edges.py <predictions>` from the predictions "
             "`scripts/measured_validation.py --save-predictions <predictions>` saves. The play ramps (±4 N·m): the "
             "+ drop is the twist given back between the end of the + peak and the unloading branch's zero torque, the "
             "− rise the same after the − peak (medians over the file's half-cycles); the model's play minus the "
             "data's is about the last two columns summed.", "", "| unit | + drop data (°) | + drop model (5–95 %) | − rise data (°) | − rise model (5–95 %) | "
             "given back, data − model (°) | peak to peak, model − data (°) |",
             "| --- | ---: | --- | ---: | --- | ---: | ---: |"]
    for r in rows:
        (dp, dm), (mp, mm), ((lp, lm), (hp, hm)) = r["data"], r["model"], r["model_range"]
        lines.append(f"| {r['unit']} | {dp:.3f} | {mp:.3f} ({lp:.3f}–{hp:.3f}) | {dm:.3f} | {mm:.3f} ({lm:.3f}–{hm:.3f}) "
                     f"| {dp - mp + dm - mm:+.3f} | {r['model_peak_to_peak'] - r['peak_to_peak']:+.3f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("predictions", type=Path, help="the folder of measured_validation.py --save-predictions")
    parser.add_argument("-o", "--output", type=Path, help="write the table here as well")
    args = parser.parse_args(argv)
    files = sorted(args.predictions.glob("*.npz"))
    if not files:
        print(f"{args.predictions}: no saved predictions (*.npz); run scripts/measured_validation.py "
              "--save-predictions <folder> first", file=sys.stderr)
        return 2
    text = markdown([loop_row(f) for f in files])
    print(text)
    if args.output:
        args.output.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
