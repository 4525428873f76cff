"""Loading-branch slopes of every measured loop, read off the data alone — REAL data
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), read where it lies, never copied.

Per file: the median over its loading branches (rising torque for τ > 0, falling for τ < 0;
branches split as ``benchmarks/repeat_reference.py`` splits them, on the running-median
torque) of the least-squares slope of twist against torque (°/N·m) within a band of |τ|, for
the play ramps (``test_nr`` < 100) and the large ramps. On the preloaded split units the play
ramps are stiffer between 2 and 4 N·m than the large ramps at high load:

    .venv/bin/python scripts/measured_branch_slopes.py
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cycloidal-jv"
sys.path.insert(0, str(ROOT / "benchmarks"))
BANDS_NM = ((2, 4), (4, 10), (10, 20), (20, 36))


def branch_slope(torque, angle_rad, lo: float, hi: float) -> float:
    """Median slope (°/N·m) of the loading branches within lo < |τ| < hi (NaN if none)."""
    from repeat_reference import branches

    b = branches(torque)
    out = []
    for k in np.unique(b):
        t, y = torque[b == k], angle_rad[b == k]
        d = np.sign(t[-1] - t[0])
        sel = (d * t > lo) & (d * t < hi)
        if sel.sum() > 20:
            out.append(np.polyfit(t[sel], np.rad2deg(y[sel]), 1)[0])
    return float(np.median(out)) if out else float("nan")


def main() -> int:
    from pi_reference import filter_torque, read_loop

    if not DATA.is_dir():
        print(f"{DATA} is absent: nothing to read")
        return 0
    head = " | ".join(f"large {lo}–{hi}" for lo, hi in BANDS_NM)
    print(f"REAL measured data (CC BY-SA 4.0). Loading-branch slope, °/N·m\n\n| file | play ramps 2–4 | {head} |")
    print("| --- |" + " ---: |" * (1 + len(BANDS_NM)))
    for path in sorted(DATA.glob("*/*.csv.gz")):
        d = read_loop(path)
        nr, angle, torque = d["test_nr"], d["angle_rad"], filter_torque(d["torque_Nm"])
        play, large = nr < 100, nr >= 100
        cells = [branch_slope(torque[play], angle[play], 2, 4)]
        cells += [branch_slope(torque[large], angle[large], lo, hi) for lo, hi in BANDS_NM]
        print(f"| {path.parent.name}-{path.name.removesuffix('.csv.gz')} | " + " | ".join(f"{c:.4f}" for c in cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
