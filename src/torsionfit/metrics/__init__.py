"""Catalog metrics from measured data alone, no model fit (DESIGN §1.4, §5.2).

- :func:`loop_branches` — a hysteresis run split into loop branches on a common torque grid;
- :func:`hysteresis_metrics` — stiffness at rated torque (secant), elastic slope, K1/K2/K3,
  lost motion, backlash, dissipated energy of one hysteresis run's full-range loop;
- :func:`play_from_arrays` / :func:`loading_compliance_from_arrays` — play (loop width at zero
  torque of the smallest cycles) and loading-branch compliances of the largest cycles, from
  plain arrays (measured or simulated); :func:`cycle_classes` groups a run's cycles by amplitude,
  :func:`loading_compliance_cycles` gives the loading compliances branch by branch and
  :func:`play_cycles` the play cycle by cycle, :func:`class_readings` both with standard errors,
  :func:`small_cycle_rows` marks the samples of the smallest cycles (the play ramps);
- :func:`hysteresis_run_metrics` — all of these for one run, with a note for each metric that
  cannot be computed;
- :func:`gap_crossings` — the torques at which the hysteresis runs' large cycles cross the
  gap (the twist's jump), rising and falling, and their centre;
- :func:`te_metrics` — K_d (180°), K_t (revolution mean) and TE levels of one TE run;
- :func:`campaign_metrics` / :func:`format_metrics_table` — all runs of a campaign, as the
  `torsionfit metrics` JSON document and as a terminal table.
"""

from ._campaign import (
    campaign_metrics as campaign_metrics,
    format_metrics_table as format_metrics_table,
    reference_run_for as reference_run_for,
)
from ._gap_crossing import (
    GapCrossings as GapCrossings,
    branch_crossing as branch_crossing,
    gap_crossings as gap_crossings,
)
from ._hysteresis import (
    AmplitudeClass as AmplitudeClass,
    CycleClasses as CycleClasses,
    LoadingFit as LoadingFit,
    LoopBranches as LoopBranches,
    Reading as Reading,
    class_readings as class_readings,
    cycle_classes as cycle_classes,
    hysteresis_metrics as hysteresis_metrics,
    hysteresis_run_metrics as hysteresis_run_metrics,
    loading_compliance_cycles as loading_compliance_cycles,
    loading_compliance_from_arrays as loading_compliance_from_arrays,
    loading_fit as loading_fit,
    loop_branches as loop_branches,
    play_from_arrays as play_from_arrays,
    play_cycles as play_cycles,
    play_of as play_of,
    small_cycle_rows as small_cycle_rows,
)
from ._te import te_metrics as te_metrics, te_profile as te_profile
