"""Catalog metrics from measured data alone, no model fit (DESIGN §1.4, §5.2).

- :func:`loop_branches` — a hysteresis run split into loop branches on a common torque grid;
- :func:`hysteresis_metrics` — stiffness at rated torque (secant), elastic slope, K1/K2/K3,
  lost motion, backlash, dissipated energy of one hysteresis run;
- :func:`te_metrics` — K_d (180°), K_t (revolution mean) and TE levels of one TE run;
- :func:`campaign_metrics` / :func:`format_metrics_table` — all runs of a campaign, as the
  `torsionfit metrics` JSON document and as a terminal table.
"""

from ._campaign import (
    campaign_metrics as campaign_metrics,
    format_metrics_table as format_metrics_table,
    reference_run_for as reference_run_for,
)
from ._hysteresis import (
    LoopBranches as LoopBranches,
    hysteresis_metrics as hysteresis_metrics,
    loop_branches as loop_branches,
)
from ._te import te_metrics as te_metrics, te_profile as te_profile
