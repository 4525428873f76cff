"""How well each large ramp of a measured file repeats the one before it, read off the data
alone — REAL data (JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), read where it lies,
never copied.

Per file: the large ramp ``b`` predicted by the ramp ``a`` before it — on the same monotone
branch, the twist at the same torque (``benchmarks/repeat_reference.py``, which splits the
branches on the running-median torque) — and the RMS of what is left (arcsec), per branch and
over the ramp. The first large ramp after the play ramps (100) against the next (101), then 101
against 102: on these files the first ramp does not repeat (its first branches are far off the
next ramp's, at the peaks too) while the later two repeat each other far better:

    .venv/bin/python scripts/measured_ramp_repeats.py
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cycloidal-jv"
sys.path.insert(0, str(ROOT / "benchmarks"))
ARCSEC = np.deg2rad(1.0 / 3600.0)
PAIRS = ((100, 101), (101, 102))


def repeat_rms(torque, angle_rad, test_nr, a: int, b: int) -> tuple[list[float], float]:
    """(RMS per branch of ramp ``b``, RMS over ramp ``b``), arcsec, of ramp ``b``'s twist less
    ramp ``a``'s on the same branch at the same torque (samples no branch of ``a`` covers left out)."""
    from repeat_reference import branches, predict_ramp

    target = test_nr == b
    left = angle_rad[target] - predict_ramp(torque, angle_rad, [test_nr == a], target)
    branch = branches(torque[target])
    ok = np.isfinite(left)
    per = [float(np.sqrt(np.mean(left[ok & (branch == k)] ** 2))) / ARCSEC for k in np.unique(branch)]
    return per, float(np.sqrt(np.mean(left[ok] ** 2))) / ARCSEC


def main() -> int:
    from pi_reference import filter_torque, read_loop

    if not DATA.is_dir():
        print(f"{DATA} is absent: nothing to read")
        return 0
    head = " | ".join(f"{b} from {a}: per branch | {b} from {a}: ramp" for a, b in PAIRS)
    print(f"REAL measured data (CC BY-SA 4.0). RMS (arcsec) of a large ramp's twist less the ramp before it's, "
          f"same branch, same torque\n\n| file | {head} |")
    print("| --- |" + " ---: | ---: |" * len(PAIRS))
    for path in sorted(DATA.glob("*/*.csv.gz")):
        d = read_loop(path)
        nr, angle, torque = d["test_nr"], d["angle_rad"], filter_torque(d["torque_Nm"])
        cells = []
        for a, b in PAIRS:
            per, whole = repeat_rms(torque, angle, nr, a, b)
            cells += [" / ".join(f"{v:.0f}" for v in per), f"{whole:.0f}"]
        print(f"| {path.parent.name}-{path.name.removesuffix('.csv.gz')} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
