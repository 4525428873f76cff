"""Tables 4 and 6 of Cheng et al. 2023 next to the paper's own evaluation of the bundled
SYNTHETIC campaigns (data alone, no model fit): secant K_s with the start-of-step-1
reference, K_d = T_r / TE(180°). Prints a Markdown table."""

import sys
from pathlib import Path

from torsionfit.io import load_campaign
from torsionfit.metrics import campaign_metrics

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = {  # N·m/°, as checked in shared/paper/TABLES.md
    ("paper-small", "hysteresis-0.02Nm_per_s"): ("Table 4", "small, 0.02 N·m/s", 0.4969),
    ("paper-small", "hysteresis-0.05Nm_per_s"): ("Table 4", "small, 0.05 N·m/s", 0.5124),
    ("paper-small", "hysteresis-0.1Nm_per_s"): ("Table 4", "small, 0.1 N·m/s", 0.5192),
    ("paper-large", "hysteresis-1Nm_per_s"): ("Table 4", "large, 1 N·m/s", 5235.1212),
    ("paper-large", "hysteresis-2.5Nm_per_s"): ("Table 4", "large, 2.5 N·m/s", 5474.5840),
    ("paper-large", "hysteresis-5Nm_per_s"): ("Table 4", "large, 5 N·m/s", 5633.3852),
    ("paper-small", "te-1rpm-1Nm-fw"): ("Table 6", "small, 1 rpm", 0.4964),
    ("paper-small", "te-5rpm-1Nm-fw"): ("Table 6", "small, 5 rpm", 0.3880),
    ("paper-small", "te-10rpm-1Nm-fw"): ("Table 6", "small, 10 rpm", 0.3517),
    ("paper-large", "te-1rpm-380Nm-fw"): ("Table 6", "large, 1 rpm", 5184.8820),
    ("paper-large", "te-5rpm-380Nm-fw"): ("Table 6", "large, 5 rpm", 5179.6992),
    ("paper-large", "te-10rpm-380Nm-fw"): ("Table 6", "large, 10 rpm", 5120.2587),
}


def rows():
    out = []
    for name in ("paper-small", "paper-large"):
        result = campaign_metrics(load_campaign(ROOT / "data" / name / "campaign.toml"))
        for run in result["runs"]:
            key = "stiffness_rated_from_start_Nm_per_deg" if run["kind"] == "hysteresis" else "kd_Nm_per_deg"
            table, condition, published = PUBLISHED[(name, run["name"])]
            got = run["metrics"][key]["value"]
            out.append((table, condition, published, got, 100 * (got / published - 1)))
    return sorted(out, key=lambda r: r[0])


def main():
    print("| table | reducer, condition | published (N·m/°) | reproduced (N·m/°) | difference |")
    print("| --- | --- | ---: | ---: | ---: |")
    for table, condition, published, got, diff in rows():
        print(f"| {table} | {condition} | {published:.4f} | {got:.4f} | {diff:+.2f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
