"""In-memory campaign: one reducer, its bench, and its runs, all in SI units."""

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Reducer:
    """The unit under test. ``rated_torque_Nm`` is optional: the data-only metrics then read
    their torque scale from the data; model fits, acceptance and the paper need it."""

    name: str
    rated_torque_Nm: float | None = None
    ratio: float | None = None
    max_speed_rpm: float | None = None


@dataclass(frozen=True)
class Instrument:
    """Bench sensors; every field optional (None = unknown)."""

    torque_full_scale_Nm: float | None = None
    torque_accuracy_pct_fs: float | None = None
    encoder_resolution_arcsec: float | None = None
    sample_rate_Hz: float | None = None
    #: the motor (input) encoder's resolution: the angle of one count of an input_angle
    #: column logged in counts (arcsec)
    input_encoder_resolution_arcsec: float | None = None
    #: sign of TE in the bench's files: "lag_positive" (a load that makes the output lag gives
    #: positive TE) or "lag_negative" (negated on reading); a run may override it
    te_convention: str = "lag_positive"

    @property
    def torque_sd_Nm(self) -> float | None:
        """Torque noise standard deviation implied by accuracy × full scale (N·m)."""
        if self.torque_full_scale_Nm is None or self.torque_accuracy_pct_fs is None:
            return None
        return self.torque_full_scale_Nm * self.torque_accuracy_pct_fs / 100.0

    @property
    def angle_floor_rad(self) -> float | None:
        """Quantisation noise floor of the encoder, resolution/√12 (rad)."""
        if self.encoder_resolution_arcsec is None:
            return None
        return float(np.deg2rad(self.encoder_resolution_arcsec / 3600.0) / np.sqrt(12.0))


@dataclass(frozen=True, eq=False)
class HysteresisRun:
    """Input locked, output loaded. Arrays are 1-D, same length, time non-decreasing."""

    name: str
    time_s: np.ndarray
    torque_Nm: np.ndarray
    angle_rad: np.ndarray
    loading_rate_Nm_per_s: float | None = None
    temperature_C: np.ndarray | None = None
    source: str = ""
    #: nominal peak load of the ramps (N·m); None = the reducer's rated torque
    peak_torque_Nm: float | None = None
    #: the manifest's ``peak_torque_Nm = "data"``: a partial-load run whose loop metrics are
    #: read at the loop's own peak (``peak_torque_Nm`` None)
    peak_from_data: bool = False
    #: nominal temperature of the run (°C, the manifest's temperature_C key)
    nominal_temperature_C: float | None = None
    #: what reading changed (e.g. a dropped pad of non-finite rows), shown by ``metrics``
    notes: tuple[str, ...] = ()
    #: per sample, True on a conditioning row (``[runs.condition]``): it drives the model's
    #: state but is out of the fit's likelihood; None: none
    conditioning: np.ndarray | None = None
    kind: str = field(default="hysteresis", init=False)

    def __len__(self) -> int:
        return len(self.time_s)


@dataclass(frozen=True, eq=False)
class TransmissionErrorRun:
    """Rotating under constant load. ``te_rad`` = θ_out − θ_in/R, output-referred."""

    name: str
    output_angle_rad: np.ndarray
    te_rad: np.ndarray
    torque_Nm: float  # nominal load, ≥ 0 (its sign is carried by ``direction``)
    speed_rpm: float  # output speed, ≥ 0
    direction: int  # +1 forward, −1 backward
    time_s: np.ndarray | None = None
    torque_series_Nm: np.ndarray | None = None
    temperature_C: np.ndarray | None = None
    source: str = ""
    #: runs with the same zero group share one TE zero (None: the campaign's common zero)
    zero_group: str | None = None
    #: the TE sign convention the run was declared with (its TE is lag-positive in memory)
    te_convention: str = "lag_positive"
    #: nominal temperature of the run (°C, the manifest's temperature_C key)
    nominal_temperature_C: float | None = None
    #: what reading changed (sign convention, dropped pad rows, derived time), shown by ``metrics``
    notes: tuple[str, ...] = ()
    #: the file column(s) the TE was read from, for messages ("column 'te_arcsec'"; "" when made
    #: in memory), and their declared angle unit
    te_column: str = ""
    te_unit: str = ""
    kind: str = field(default="transmission_error", init=False)

    def __len__(self) -> int:
        return len(self.output_angle_rad)


Run = HysteresisRun | TransmissionErrorRun


def reference_temperature_C(temperatures) -> float | None:
    """The median of the distinct known temperatures (°C; None entries ignored, None when
    none is known): what a temperature-dependent model's ΔT = 0 means."""
    known = sorted({float(t) for t in temperatures if t is not None})
    return float(np.median(known)) if known else None


@dataclass(frozen=True, eq=False)
class Campaign:
    """One unit: reducer, instrument and runs. ``path`` is the manifest it came from."""

    reducer: Reducer
    instrument: Instrument
    runs: tuple[Run, ...]
    path: Path | None = None
    notes: str = ""

    @property
    def hysteresis_runs(self) -> tuple[HysteresisRun, ...]:
        return tuple(r for r in self.runs if isinstance(r, HysteresisRun))

    @property
    def te_runs(self) -> tuple[TransmissionErrorRun, ...]:
        return tuple(r for r in self.runs if isinstance(r, TransmissionErrorRun))

    @property
    def te_zero_groups(self) -> tuple[str | None, ...]:
        """The TE zero groups in order of first use (None: runs without ``zero_group``)."""
        return tuple(dict.fromkeys(r.zero_group for r in self.te_runs))

    def te_zero_index(self, run: TransmissionErrorRun) -> int:
        """Index of ``run``'s zero group in :attr:`te_zero_groups` (the model's ``te_offset``)."""
        return self.te_zero_groups.index(run.zero_group)

    @staticmethod
    def run_temperature_C(run: Run) -> float | None:
        """A run's temperature (°C): its ``temperature_C`` key, else the median of its
        temperature column, else None."""
        if run.nominal_temperature_C is not None:
            return float(run.nominal_temperature_C)
        if run.temperature_C is not None and np.any(np.isfinite(run.temperature_C)):
            return float(np.nanmedian(run.temperature_C))
        return None

    @functools.cached_property
    def reference_temperature_C(self) -> float | None:
        """The temperature a temperature-dependent model's metrics refer to (°C): the median of
        the distinct run temperatures; None when no run has one. Computed once (the runs are
        fixed): every run's ΔT reads it."""
        return reference_temperature_C(self.run_temperature_C(r) for r in self.runs)

    def temperature_delta_K(self, run: Run) -> float:
        """``run``'s temperature above :attr:`reference_temperature_C` (K; 0 when unknown)."""
        t, ref = self.run_temperature_C(run), self.reference_temperature_C
        return 0.0 if t is None or ref is None else t - ref
