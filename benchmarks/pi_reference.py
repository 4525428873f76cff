"""Specialist reference fit for measured hysteresis loops: Prandtl–Ishlinskii + gap, by NNLS.

A deliberately plain NumPy/SciPy model, independent of torsionfit, that the main model's fits of
the measured cycloidal-reducer loops are compared against:

    angle(t) ≈ Σ_i a_i · P_{r_i}[τ_f](t) + Σ_j b_j · tanh((τ_f(t) − c_j) / w) + c⁺ − c⁻

- ``τ_f``: the measured torque after a running median (``MEDIAN_WINDOW`` samples);
- ``P_r``: the play (backlash) operator of threshold ``r`` (Prandtl–Ishlinskii / Maxwell-slip
  element), ``N_PLAY`` thresholds r_i = i·H/N_PLAY, i = 0..N_PLAY−1, with H the half-range of
  the filtered torque on the rows the fit sees (r = 0 is the identity, i.e. a linear compliance
  column; r = H itself is left out, see ``PIReference.design``);
- ``tanh`` columns: ``N_GAP`` smooth steps at centres spread uniformly over
  ``[−GAP_SPAN, +GAP_SPAN]`` N·m with width ``GAP_WIDTH`` N·m, modelling the play (gap) that the
  reducer crosses near zero torque;
- ``b_j ≥ 0`` (the gap only ever adds twist in the direction of the torque) and the play weights
  ``a_i`` of either sign: each play column with r > 0 enters as ``+P`` and ``−P`` (the offset too,
  as a + and a − column), all solved by ``scipy.optimize.nnls``. Signed play weights are needed on
  these loops: the motor-current torque estimate crosses the gap *ahead* of the load (on rising
  torque the twist jumps at τ ≈ −3 N·m, on falling torque at τ ≈ +3 N·m), a counter-clockwise loop
  that a sum of play operators with non-negative weights (always clockwise) cannot draw.
  ``signed_play=False`` is the classic non-negative PI (measured: 689″ instead of 486″ in sample
  on baseline initial-pos1, 946″ instead of 494″ on initial-pos6).

Variant ``hyst_gap=True`` ("PI + hysteretic gap"): the gap columns are in addition evaluated on
the lagging and the leading play-operated torque, ``tanh((P_r[τ_f] − c_j)/w)`` and
``tanh((2τ_f − P_r[τ_f] − c_j)/w)`` for r in ``HYST_GAP_THRESHOLDS`` (weights ≥ 0), so the gap
crossing itself can be hysteretic. Stronger (e.g. 353″ in sample on baseline initial-pos1) and
reported beside the default, which keeps the project's specified design (tanh of τ_f only).

Variant *gap lag* (``PIReference.fit_lagged``): the gap columns see the filtered torque
through a first-order lag ``T·dy/dt = τ_f − y`` (a damped gap crossing), T chosen from
``LAG_GRID_S`` by the RMSE on the fitted rows. On these loops the gap is crossed a fraction of a
second late while the twist turns with the torque at the peaks, and the lag lowers the
reference's held-out RMSE on most files: the stronger reference for a model that has the lag
too.

The play operators run over the whole file in time order, so the state at the start of a ramp is
carried from the samples before it: a fit to some ramps predicts a later ramp with the right
initial state.

Usage (from the repository root)::

    .venv/bin/python benchmarks/pi_reference.py                    # all files, writes results/pi_reference.md/.json
    .venv/bin/python benchmarks/pi_reference.py --data DIR -o out.md

REAL measured data: JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0 (read from
``<repo>/../shared/data/cycloidal-jv``; nothing of it is stored in this repository).
"""

from __future__ import annotations

import argparse
import csv
import gzip
import json
import os
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.ndimage import median_filter
from scipy.optimize import nnls

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cycloidal-jv"
ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0
LICENCE = "REAL measured data: JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0"

# design of the reference (see the module docstring)
MEDIAN_WINDOW = 21  # samples (~54 ms at ~390 Hz), centred running median of the torque
N_PLAY = 20  # play-operator thresholds r_i = i·H/N_PLAY, H = half-range of the filtered torque
N_GAP = 6  # tanh gap columns
GAP_SPAN = 4.0  # N·m: gap centres uniform in [-GAP_SPAN, +GAP_SPAN] (the play ramps reach ±4 N·m)
GAP_WIDTH = 1.0  # N·m: tanh width
SIGNED_PLAY = True  # play columns enter as +P and -P (r > 0): generalised PI, weights of either sign
# the stronger "hysteretic gap" variant: the gap steps also as functions of the lagging and the
# leading play-operated torque, P_r[τ] and 2τ − P_r[τ], for these thresholds (N·m)
HYST_GAP_THRESHOLDS = (1.0, 2.0, 3.0, 4.0)


def read_loop(path) -> dict[str, np.ndarray]:
    """Read one raw bench CSV (plain or gzip): time_s, torque_Nm, angle_rad, test_nr."""
    path = Path(path)
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        idx = [header.index(c) for c in ("TIME", "POSITION", "TORQUE", "test_nr")]
        rows = [[row[i] for i in idx] for row in reader if row]
    arr = np.array(rows, dtype=float)
    return {
        "time_s": arr[:, 0],
        "torque_Nm": arr[:, 2],
        "angle_rad": arr[:, 1] * 2.0 * np.pi,
        "test_nr": arr[:, 3].astype(int),
    }


def play_operator(x, r, y0=None) -> np.ndarray:
    """Play (backlash) operator ``y_n = min(max(y_{n-1}, x_n - r), x_n + r)`` for all ``r`` at once.

    ``x``: (N,) input; ``r``: scalar or (K,) thresholds ≥ 0; ``y0``: the state before the first
    sample (scalar or (K,)); default ``x_0`` clamped, i.e. the operator starts relaxed at ``x_0``.
    Returns (N, K) (or (N,) for a scalar ``r``).
    """
    x = np.asarray(x, dtype=float)
    r_arr = np.atleast_1d(np.asarray(r, dtype=float))
    if np.any(r_arr < 0):
        raise ValueError("thresholds must be >= 0")
    y = np.full(r_arr.shape, x[0]) if y0 is None else np.broadcast_to(np.asarray(y0, float), r_arr.shape).copy()
    lo, hi = x[:, None] - r_arr, x[:, None] + r_arr
    out = np.empty((x.size, r_arr.size))
    for n in range(x.size):  # K-wide NumPy ops per sample; ~0.1 s for 35 000 samples
        y = np.minimum(np.maximum(y, lo[n]), hi[n])
        out[n] = y
    return out if np.ndim(r) else out[:, 0]


def lag_torque(time_s, torque, lag_s: float) -> np.ndarray:
    """The torque through a first-order lag ``T·dy/dt = τ − y`` (exact for a torque linear
    between samples, starting at rest at the first sample; ``lag_s = 0``: unchanged)."""
    torque = np.asarray(torque, float)
    if lag_s <= 0:
        return torque
    dt = np.diff(np.asarray(time_s, float))
    x = dt / lag_s
    e = np.exp(-x)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(x > 0, -np.expm1(-x) / np.where(x > 0, x, 1.0), 1.0)
    b = torque[1:] - e * torque[:-1] - g * np.diff(torque)
    out = np.empty_like(torque)
    out[0] = torque[0]
    for n in range(1, torque.size):
        out[n] = e[n - 1] * out[n - 1] + b[n - 1]
    return out


#: lags (s) the lagged reference chooses from, by its RMSE on the rows it is fitted to
LAG_GRID_S = (0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.4)


def filter_torque(torque, window: int = MEDIAN_WINDOW) -> np.ndarray:
    """Centred running median of the torque (edges: nearest value)."""
    return median_filter(np.asarray(torque, float), size=window, mode="nearest")


@dataclass
class PIReference:
    """PI (play operators) + tanh gap + free offset, by NNLS (see the module docstring for signs).

    ``fit(torque, angle, mask)`` builds the columns over the whole record (state carried through
    time) and fits on the rows in ``mask``; ``predict()`` returns the angle for every row.
    """

    median_window: int = MEDIAN_WINDOW
    n_play: int = N_PLAY
    n_gap: int = N_GAP
    gap_span: float = GAP_SPAN
    gap_width: float = GAP_WIDTH
    signed_play: bool = SIGNED_PLAY
    hyst_gap: bool = False
    hyst_gap_thresholds: tuple = HYST_GAP_THRESHOLDS
    gap_lag_s: float = 0.0  # first-order lag of the torque the gap columns see (0: none)
    thresholds: np.ndarray | None = field(default=None, repr=False)
    centres: np.ndarray | None = field(default=None, repr=False)
    weights: np.ndarray | None = field(default=None, repr=False)
    _X: np.ndarray | None = field(default=None, repr=False)
    _scale: np.ndarray | None = field(default=None, repr=False)

    def design(self, torque, mask=None, time_s=None) -> np.ndarray:
        """Columns for the whole record; thresholds from the filtered torque on ``mask`` rows;
        ``time_s`` is needed for a gap lag."""
        tau = filter_torque(torque, self.median_window)
        if self.gap_lag_s > 0 and time_s is None:
            raise ValueError("a gap lag needs the samples' time_s")
        tau_gap = lag_torque(time_s, tau, self.gap_lag_s) if self.gap_lag_s > 0 else tau
        seen = tau if mask is None else tau[mask]
        half_range = 0.5 * (seen.max() - seen.min())
        # r_i = i·H/N, i = 0..N−1: the endpoint r = H is left out, as a play operator of threshold
        # H only moves when the torque goes beyond every earlier extreme — a column that is a
        # one-off step inside the fitted data and explodes when a later ramp sets a new record
        # (measured: 10 029″ out of sample on split preload3-pos6 with it, 1 143″ without)
        self.thresholds = half_range * np.arange(self.n_play) / self.n_play
        self.centres = np.linspace(-self.gap_span, self.gap_span, self.n_gap) if self.n_gap else np.zeros(0)
        play = play_operator(tau, self.thresholds)
        cols = [play, -play[:, 1:]] if self.signed_play else [play]
        cols.append(np.tanh((tau_gap[:, None] - self.centres) / self.gap_width))
        if self.hyst_gap:
            lag = play_operator(tau, np.asarray(self.hyst_gap_thresholds, float))
            for drive in (lag, 2.0 * tau[:, None] - lag):  # lagging and leading torque
                for k in range(drive.shape[1]):
                    cols.append(np.tanh((drive[:, k : k + 1] - self.centres) / self.gap_width))
        ones = np.ones((tau.size, 1))
        return np.hstack(cols + [ones, -ones])

    @property
    def play_weights(self) -> np.ndarray:
        """Net weight of each play operator (the +P minus the −P column)."""
        a = self.weights[: self.n_play].copy()
        if self.signed_play:
            a[1:] -= self.weights[self.n_play : 2 * self.n_play - 1]
        return a

    def fit_lagged(self, time_s, torque, angle, mask=None, grid=LAG_GRID_S) -> tuple["PIReference", float]:
        """The fit with the gap columns on the filtered torque through a first-order lag (a damped
        gap crossing), the lag chosen from ``grid`` by the RMSE on the ``mask`` rows (never the
        held-out ones): (fit, lag in s)."""
        angle = np.asarray(angle, float)
        m = np.ones(angle.size, bool) if mask is None else np.asarray(mask, bool)
        best = None
        for lag in grid:
            fit = replace(self, gap_lag_s=float(lag)).fit(torque, angle, m, time_s=time_s)
            err = float(np.mean((fit.predict()[m] - angle[m]) ** 2))
            if best is None or err < best[0]:
                best = (err, fit, float(lag))
        return best[1], best[2]

    def fit(self, torque, angle, mask=None, time_s=None) -> "PIReference":
        angle = np.asarray(angle, float)
        mask = np.ones(angle.size, bool) if mask is None else np.asarray(mask, bool)
        X = self.design(torque, mask, time_s)
        scale = np.sqrt(np.mean(X[mask] ** 2, axis=0))  # equilibrate columns (NNLS is scale-invariant)
        scale[scale == 0] = 1.0
        # NNLS on the triangular factor: ||A w − y||² = ||R w − Qᵀy||² + const for A = QR, so the
        # k×k problem has the same solution as the n×k one (k ≈ 50–100 columns, n ≈ 26 000 rows)
        # and NNLS's active-set iterations no longer touch all rows
        q, r = np.linalg.qr(X[mask] / scale, mode="reduced")
        w, _ = nnls(r, q.T @ angle[mask], maxiter=50 * X.shape[1])
        self.weights, self._X, self._scale = w / scale, X, scale
        return self

    def predict(self) -> np.ndarray:
        return self._X @ self.weights


def rmse_arcsec(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)) * ARCSEC_PER_RAD)


def evaluate(path, variants: bool = True, **model_kw) -> dict:
    """RMSE figures (arcsec) for one file, plus the time taken.

    - ``in_sample``: fit to the large ramps (test_nr ≥ 100), RMSE on them;
    - ``oos_rest``: fit to every sample except the last large ramp (small play ramps + earlier
      large ramps), RMSE on the last large ramp;
    - ``oos_large``: fit to the earlier large ramps only, RMSE on the last large ramp;
    - ``seconds``: wall time of reading the file and the three fits of the default model.

    ``model_kw`` go to ``PIReference``. With ``variants`` the same three figures are added for the
    hysteretic-gap variant (keys ``hyst_gap_in_sample`` …, timed separately in
    ``hyst_gap_seconds``).
    """
    t0 = time.perf_counter()
    d = read_loop(path)
    tau, ang, nr = d["torque_Nm"], d["angle_rad"], d["test_nr"]
    large = nr >= 100
    last = nr == nr.max()
    y = ang - ang.mean()  # the offset column absorbs it; keeps NNLS well scaled
    out = {"file": str(path), "n": int(ang.size), "last_ramp": int(nr.max())}
    setups = [("", {})]
    if variants:
        setups.append(("hyst_gap_", {"hyst_gap": True}))
    for prefix, extra in setups:
        t1 = time.perf_counter()
        for key, fit_mask in (("in_sample", large), ("oos_rest", ~last), ("oos_large", large & ~last)):
            m = PIReference(**{**model_kw, **extra}).fit(tau, y, fit_mask)
            eval_mask = large if key == "in_sample" else last
            out[prefix + key] = rmse_arcsec(m.predict()[eval_mask], y[eval_mask])
            if key == "in_sample":
                out[prefix + "n_columns"] = int(m.weights.size)
        out[prefix + "seconds"] = time.perf_counter() - (t0 if not prefix else t1)
    return out


def data_files(data_dir) -> list[Path]:
    return sorted(Path(data_dir).glob("*/*.csv.gz"))


def _markdown(rows, data_dir) -> str:
    lines = [
        "# Prandtl–Ishlinskii + gap reference fit (NNLS) on measured hysteresis loops",
        "",
        f"**{LICENCE}** (files read from `{data_dir}`, not stored here).",
        "",
        f"**Model (default, the reference).** {N_PLAY} play operators of the torque after a "
        f"{MEDIAN_WINDOW}-sample centred running median (thresholds r_i = i·H/{N_PLAY}, i = 0…{N_PLAY - 1}, "
        "H = half-range of the filtered torque on the fitted rows), each with r > 0 as a +P and a −P column (net "
        f"weight of either sign), + {N_GAP} tanh gap columns tanh((τ_f − c_j)/w), centres uniform in "
        f"±{GAP_SPAN:g} N·m, w = {GAP_WIDTH:g} N·m, weights ≥ 0, + a free offset (± columns); solved "
        "by `scipy.optimize.nnls`; play-operator state carried through the whole file in time order.",
        "",
        "**Variant *hyst. gap*.** The same plus the gap columns evaluated on the lagging and the "
        "leading play-operated torque, P_r[τ_f] and 2τ_f − P_r[τ_f], r ∈ "
        f"{{{', '.join(f'{r:g}' for r in HYST_GAP_THRESHOLDS)}}} N·m (weights ≥ 0): the gap crossing "
        "itself hysteretic.",
        "",
        "RMSE of the output angle in arcsec (encoder step 19.78″). *in sample*: fit to the large ramps "
        "(test_nr ≥ 100), RMSE on them. *OOS rest*: fit to every sample except the last large ramp "
        "(small play ramps + earlier large ramps), RMSE on the last large ramp. *OOS large*: fit to "
        "the earlier large ramps only, RMSE on the last large ramp. *s*: wall time per file (read + "
        "three fits) of the default model; of the variant's three fits in brackets.",
        "",
        "| file | in sample [″] | OOS rest [″] | OOS large [″] | hyst. gap: in sample [″] | hyst. gap: OOS rest [″] | hyst. gap: OOS large [″] | s |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        lines.append(
            f"| {r['name']} | {r['in_sample']:.0f} | {r['oos_rest']:.0f} | {r['oos_large']:.0f} "
            f"| {r['hyst_gap_in_sample']:.0f} | {r['hyst_gap_oos_rest']:.0f} | {r['hyst_gap_oos_large']:.0f} "
            f"| {r['seconds']:.1f} ({r['hyst_gap_seconds']:.1f}) |"
        )
    keys = ["in_sample", "oos_rest", "oos_large", "hyst_gap_in_sample", "hyst_gap_oos_rest", "hyst_gap_oos_large"]
    med = {k: float(np.median([r[k] for r in rows])) for k in keys}
    lines.append(
        f"| **median of {len(rows)}** | {med['in_sample']:.0f} | {med['oos_rest']:.0f} | {med['oos_large']:.0f} "
        f"| {med['hyst_gap_in_sample']:.0f} | {med['hyst_gap_oos_rest']:.0f} | {med['hyst_gap_oos_large']:.0f} | |"
    )
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data", type=Path, default=DATA, help="folder with <design>/<state>-<pos>.csv.gz")
    p.add_argument("-o", "--output", type=Path, default=ROOT / "benchmarks" / "results" / "pi_reference.md")
    a = p.parse_args(argv)
    files = data_files(a.data) if a.data.is_dir() else []
    if not files:
        print(f"no measured data in {a.data}: nothing to do")
        return 0
    load0 = os.getloadavg()[0]
    rows = []
    for f in files:
        r = evaluate(f)
        r["name"] = f"{f.parent.name}/{f.name.removesuffix('.csv.gz')}"
        r["file"] = r["name"]
        rows.append(r)
        print(f"{r['name']:28s} in {r['in_sample']:5.0f}  oos-rest {r['oos_rest']:5.0f}  "
              f"oos-large {r['oos_large']:5.0f}  {r['seconds']:4.1f} s | hyst. gap in {r['hyst_gap_in_sample']:5.0f}  "
              f"oos-rest {r['hyst_gap_oos_rest']:5.0f}  oos-large {r['hyst_gap_oos_large']:5.0f}  "
              f"{r['hyst_gap_seconds']:4.1f} s", flush=True)
    a.output.parent.mkdir(parents=True, exist_ok=True)
    shown_dir = a.data
    try:
        shown_dir = Path("..") / a.data.resolve().relative_to(ROOT.parent)
    except ValueError:
        pass
    load = (load0, os.getloadavg()[0])
    md = _markdown(rows, shown_dir)
    md += (f"\nMachine: {os.cpu_count()} CPUs shared with other processes, load average (1 min) "
           f"{load[0]:.1f} at start, {load[1]:.1f} at end: the seconds vary with that load.\n")
    a.output.write_text(md)
    meta = {
        "data": LICENCE,
        "model": {"median_window": MEDIAN_WINDOW, "n_play": N_PLAY, "n_gap": N_GAP,
                  "gap_span_Nm": GAP_SPAN, "gap_width_Nm": GAP_WIDTH, "signed_play": SIGNED_PLAY,
                  "thresholds": "r_i = i*H/n_play, i = 0..n_play-1, H = half-range of the filtered torque on the fitted rows",
                  "hyst_gap_thresholds_Nm": list(HYST_GAP_THRESHOLDS)},
        "units": {"rmse": "arcsec", "seconds": "s"},
        "load_average_1min": {"start": load[0], "end": load[1]},
        "rows": [{k: v for k, v in r.items() if k != "name"} for r in rows],
    }
    a.output.with_suffix(".json").write_text(json.dumps(meta, indent=2) + "\n")
    print(f"wrote {a.output} and {a.output.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
