"""The published numbers of Cheng et al. 2023 (Tables 4 and 6 and the text), as checked in
``shared/paper/TABLES.md``, keyed by the bundled SYNTHETIC campaign and run that reproduces each.

Stiffness in the paper's unit, N·m/° (``Nm/deg``); every other value says its unit in its name.
"""

from dataclasses import dataclass

CITATION = ('Cheng, Shi, Yu, Zuo, "Dynamic Torsional Stiffness of Reducers and Its Testing Method", '
            "Appl. Sci. 2023, 13(16), 9277, doi:10.3390/app13169277")
#: how every figure and page names the data it shows
SYNTHETIC_LABEL = "SYNTHETIC data calibrated to the published tables"
#: the bundled campaigns, by reducer
CAMPAIGNS = {"small": "paper-small", "large": "paper-large"}
PUBLISHED_UNIT = "Nm/deg"


@dataclass(frozen=True)
class PublishedValue:
    """One published stiffness: ``table`` ("table4" or "table6"), the reducer ("small" or
    "large"), the condition (a loading rate in N·m/s or an output speed in rpm), the run of the
    bundled campaign that reproduces it and the value in N·m/°."""

    table: str
    reducer: str
    run: str
    value_Nm_per_deg: float
    loading_rate_Nm_per_s: float | None = None
    speed_rpm: float | None = None

    @property
    def condition(self) -> str:
        if self.table == "table4":
            return f"{self.loading_rate_Nm_per_s:g} N·m/s"
        return f"{self.speed_rpm:g} rpm"

    @property
    def campaign(self) -> str:
        return CAMPAIGNS[self.reducer]


def _t4(reducer, rate, value):
    return PublishedValue("table4", reducer, f"hysteresis-{rate:g}Nm_per_s", value, loading_rate_Nm_per_s=rate)


def _t6(reducer, speed, torque, value):
    return PublishedValue("table6", reducer, f"te-{speed:g}rpm-{torque:g}Nm-fw", value, speed_rpm=speed)


#: Table 4 (K_s, hysteresis-curve method at the 180° position) and Table 6 (K_d at 180° by the
#: transmission-error method at rated load), in the papers' order
PUBLISHED: tuple[PublishedValue, ...] = (
    _t4("small", 0.02, 0.4969), _t4("small", 0.05, 0.5124), _t4("small", 0.1, 0.5192),
    _t4("large", 1.0, 5235.1212), _t4("large", 2.5, 5474.5840), _t4("large", 5.0, 5633.3852),
    _t6("small", 1.0, 1.0, 0.4964), _t6("small", 5.0, 1.0, 0.3880), _t6("small", 10.0, 1.0, 0.3517),
    _t6("large", 1.0, 380.0, 5184.8820), _t6("large", 5.0, 380.0, 5179.6992), _t6("large", 10.0, 380.0, 5120.2587),
)

#: rated torques, paper Table 2 (N·m)
RATED_TORQUE_NM = {"small": 1.0, "large": 380.0}

#: numbers the paper's text prints, as printed (units as printed, too)
TEXT = {
    # Section 4.2: "for the large reducer, it decreases from 4.3552° to 4.0473°"
    "large_angle_slowest_printed_deg": 4.3552,
    "large_angle_fastest_printed_deg": 4.0473,
    # Section 4.3: "transmission error values increasing from 4.3974° to 4.4529°"
    "large_te_1rpm_printed_deg": 4.3974,
    "large_te_10rpm_printed_deg": 4.4529,
    # Section 4.3: "the transmission error value rises from 2.0128° to 2.8436°"
    "small_te_1rpm_printed_deg": 2.0128,
    # Section 4.3: "... decreasing from 5184.8820 Nm/° to 5122.587 Nm/°"
    "large_kd_10rpm_printed_Nm_per_deg": 5122.587,
}


def published(table: str | None = None, reducer: str | None = None) -> tuple[PublishedValue, ...]:
    """The published values of ``table`` and ``reducer`` (None: all)."""
    return tuple(p for p in PUBLISHED if (table is None or p.table == table)
                 and (reducer is None or p.reducer == reducer))
