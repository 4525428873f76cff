"""The paper's internal inconsistencies (``shared/paper/TABLES.md``), each with the arithmetic
that shows it: pure functions of the published numbers, so the page states what is computed."""

from dataclasses import dataclass

from ._published import RATED_TORQUE_NM, TEXT, published

ARCMIN_PER_DEG = 60.0


@dataclass(frozen=True)
class Inconsistency:
    """``statement``: what the paper says; ``check``: the computation, with its numbers;
    ``confirmed``: whether the computation shows the inconsistency."""

    key: str
    title: str
    statement: str
    check: str
    confirmed: bool


def _value(table: str, reducer: str, index: int) -> float:
    return published(table, reducer)[index].value_Nm_per_deg


def arcmin_printed_as_degrees(rel_tol: float = 1e-4) -> Inconsistency:
    """The large reducer's angles and TE in the text match Tables 4 and 6 only in arcminutes."""
    rated = RATED_TORQUE_NM["large"]
    pairs = [
        ("large_angle_slowest_printed_deg", _value("table4", "large", 0)),
        ("large_angle_fastest_printed_deg", _value("table4", "large", 2)),
        ("large_te_1rpm_printed_deg", _value("table6", "large", 0)),
        ("large_te_10rpm_printed_deg", _value("table6", "large", 2)),
    ]
    lines, ok = [], True
    for key, table in pairs:
        printed = TEXT[key]
        as_deg = rated / printed
        as_arcmin = rated / (printed / ARCMIN_PER_DEG)
        ok &= abs(as_arcmin / table - 1) < rel_tol and abs(as_deg / table - 1) > 0.5
        lines.append(f"{rated:g} / {printed:g}° = {as_deg:.2f} N·m/°, but {rated:g} / ({printed:g}/60)° = "
                     f"{as_arcmin:.1f} N·m/° against the table's {table:.4f}")
    return Inconsistency(
        "arcmin_as_degrees", "Arcminutes printed as degrees",
        "Sections 4.2–4.3 give the large reducer's angles as 4.3552° → 4.0473° and its TE as "
        "4.3974° → 4.4529°; with 380 N·m these match Tables 4 and 6 only if they are arcminutes.",
        "; ".join(lines) + ".", ok)


def small_te_mismatch(rounding_Nm_per_deg: float = 0.5e-4) -> Inconsistency:
    """Text: small-reducer TE 2.0128° at 1 rpm; Table 6: K_d = 0.4964 N·m/°, which needs 2.0145°."""
    rated = RATED_TORQUE_NM["small"]
    printed = TEXT["small_te_1rpm_printed_deg"]
    table = _value("table6", "small", 0)
    from_text = rated / printed
    implied = rated / table
    ok = abs(from_text - table) > rounding_Nm_per_deg
    return Inconsistency(
        "small_te_0p4964", "0.4964 N·m/° does not follow from 2.0128°",
        "Section 4.3: the small reducer's TE at 1 rpm is 2.0128°; Table 6: K_d = 0.4964 N·m/°.",
        f"{rated:g} / {printed:g}° = {from_text:.5f} N·m/° ≠ {table:.4f} (beyond the table's rounding "
        f"of ±{rounding_Nm_per_deg:g}); the table implies {rated:g} / {table:.4f} = {implied:.4f}°.", ok)


def large_kd_typo(rel_tol: float = 1e-4) -> Inconsistency:
    """Text: large K_d at 10 rpm 5122.587 N·m/°; Table 6: 5120.2587, which the TE 4.4529′ gives."""
    rated = RATED_TORQUE_NM["large"]
    text = TEXT["large_kd_10rpm_printed_Nm_per_deg"]
    table = _value("table6", "large", 2)
    from_te = rated / (TEXT["large_te_10rpm_printed_deg"] / ARCMIN_PER_DEG)
    ok = abs(from_te / table - 1) < rel_tol and abs(text / table - 1) > rel_tol
    return Inconsistency(
        "large_kd_5122p587", "5122.587 is a typo for 5120.2587",
        "Section 4.3: the large reducer's K_d falls to 5122.587 N·m/° at 10 rpm; Table 6 says 5120.2587.",
        f"{rated:g} / (4.4529/60)° = {from_te:.4f} N·m/°, the table's {table:.4f} (to {abs(from_te / table - 1):.1e}); "
        f"the text's {text:g} differs from it by {text - table:+.4f} N·m/°: it reads as 5120.2587 with "
        "its \"0.\" lost.", ok)


def inconsistencies() -> tuple[Inconsistency, ...]:
    """Every inconsistency with its check, in the order of TABLES.md."""
    return (arcmin_printed_as_degrees(), small_te_mismatch(), large_kd_typo())
