"""Tables 4 and 6 of Cheng et al. 2023 next to the paper's own evaluation of the bundled
SYNTHETIC campaigns (data alone, no model fit): secant K_s with the start-of-step-1
reference, K_d = T_r / TE(180°). Prints a Markdown table. The published values and the
evaluation are ``torsionfit.paper``'s (``torsionfit paper`` adds the model's HDIs)."""

import sys
from pathlib import Path

from torsionfit.io import load_campaign
from torsionfit.metrics import campaign_metrics
from torsionfit.paper import PUBLISHED, reproduced_value

ROOT = Path(__file__).resolve().parents[1]


def rows():
    metrics = {}
    for name in ("paper-small", "paper-large"):
        result = campaign_metrics(load_campaign(ROOT / "data" / name / "campaign.toml"))
        metrics[name] = {run["name"]: run["metrics"] for run in result["runs"]}
    out = []
    for p in PUBLISHED:
        got = reproduced_value(metrics[p.campaign], p)
        table = "Table 4" if p.table == "table4" else "Table 6"
        out.append((table, f"{p.reducer}, {p.condition}", p.value_Nm_per_deg, got, 100 * (got / p.value_Nm_per_deg - 1)))
    return out


def main():
    print("| table | reducer, condition | published (N·m/°) | reproduced (N·m/°) | difference |")
    print("| --- | --- | ---: | ---: | ---: |")
    for table, condition, published, got, diff in rows():
        print(f"| {table} | {condition} | {published:.4f} | {got:.4f} | {diff:+.2f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
