"""The decision rule (JCGM 106 style): from the probability of conformance p_c to accept, reject
or indeterminate (retest), with the specific consumer's and producer's risks.

p_c is the posterior mass inside the tolerance, per requirement and for all requirements jointly
— the joint one from the same draws (the fraction of draws that meet every requirement), never a
product of marginals: the metrics of one unit are correlated (stiffness, lost motion and K_d all
move with the same spring and gap).
"""

from dataclasses import dataclass

import numpy as np

ACCEPT, REJECT, INDETERMINATE = "accept", "reject", "indeterminate"
#: exit codes of ``torsionfit accept`` (2 is the CLI's bad-input code)
EXIT_CODE = {ACCEPT: 0, REJECT: 3, INDETERMINATE: 4}


def decide(p_conform: float, p_accept: float) -> str:
    """Accept if p_c ≥ p_accept, reject if 1 − p_c ≥ p_accept (i.e. p_c ≤ 1 − p_accept, written
    so that both thresholds are exact in floating point), otherwise indeterminate."""
    if p_conform >= p_accept:
        return ACCEPT
    if 1.0 - p_conform >= p_accept:
        return REJECT
    return INDETERMINATE


def risk_from_draws(risk: float, n_draws: int) -> tuple[float, bool]:
    """(value, is an upper bound) of a risk estimated as a fraction of ``n_draws`` draws: a
    fraction of 0 is not a risk of 0 but one below the draws' resolution, ``< 1/n_draws``."""
    return (1.0 / n_draws, True) if risk == 0.0 else (risk, False)


def risk_text(risk: float, is_bound: bool, n_draws: int) -> str:
    """``0.0123``, or ``< 0.00025 (no draw of 4000 fails)`` for a bound."""
    return f"< {risk:.2g} (no draw of {n_draws} fails)" if is_bound else f"{risk:.3g}"


@dataclass(frozen=True)
class Decision:
    """The decision for one unit. ``consumer_risk`` (1 − p_c) is set for an accepted unit,
    ``producer_risk`` (p_c) for a rejected one, both None otherwise. Both are fractions of
    ``n_draws`` draws: when no draw fails the risk is reported as the bound 1/``n_draws`` with
    ``risk_is_bound`` True (the draws cannot resolve a smaller risk; it is not zero)."""

    decision: str
    p_conform: float  # joint, all requirements
    p_accept: float
    requirement_p_conform: tuple[float, ...]
    requirement_decisions: tuple[str, ...]
    consumer_risk: float | None
    producer_risk: float | None
    reason: str
    n_draws: int
    risk_is_bound: bool = False


def decide_unit(conform: np.ndarray, names, p_accept: float, converged: bool = True,
                not_converged_reason: str = "", withheld_reason: str = "") -> Decision:
    """Decide from ``conform`` (draws × requirements, bool: does the draw meet the requirement).

    A posterior that did not converge gives ``indeterminate`` for the unit and every requirement,
    with the reason; its p_c are reported but never used for a decision. So does a
    ``withheld_reason`` (a requirement on a metric the model is known not to draw)."""
    conform = np.asarray(conform, bool)
    if conform.ndim != 2 or conform.shape[1] != len(names) or conform.shape[0] == 0:
        raise ValueError(f"conform must be (draws > 0, {len(names)}), got {conform.shape}")
    p_each = tuple(float(p) for p in conform.mean(axis=0))
    p_joint = float(np.all(conform, axis=1).mean())
    n = conform.shape[0]
    if not converged or withheld_reason:
        why = not_converged_reason or "the sampler's diagnostics say converged: false"
        reason = (f"no decision: {withheld_reason}" if converged else
                  f"no decision from a posterior that has not converged ({why})") + f"; joint p_c would be {p_joint:.4g}"
        return Decision(INDETERMINATE, p_joint, p_accept, p_each, (INDETERMINATE,) * len(names),
                        None, None, reason, n)
    each = tuple(decide(p, p_accept) for p in p_each)
    decision = decide(p_joint, p_accept)
    listing = ", ".join(f"{name} {p:.4g}" for name, p in zip(names, p_each))
    if decision == ACCEPT:
        reason = f"joint p_c {p_joint:.4g} >= p_accept {p_accept:g} (per requirement: {listing})"
    elif decision == REJECT:
        failing = ", ".join(f"{name} (p_c {p:.4g})" for name, p, d in zip(names, p_each, each) if d == REJECT)
        reason = (f"joint p_c {p_joint:.4g} <= 1 - p_accept {1 - p_accept:.4g}"
                  + (f"; failing: {failing}" if failing else f" (per requirement: {listing})"))
    else:
        reason = (f"joint p_c {p_joint:.4g} between {1 - p_accept:.4g} and {p_accept:g}: retest or measure "
                  f"more (per requirement: {listing})")
    risk, bound = risk_from_draws(1.0 - p_joint if decision == ACCEPT else p_joint, n)
    if decision in (ACCEPT, REJECT):
        who = "consumer" if decision == ACCEPT else "producer"
        reason += f"; specific {who}'s risk {risk_text(risk, bound, n)}"
    return Decision(decision, p_joint, p_accept, p_each, each,
                    risk if decision == ACCEPT else None, risk if decision == REJECT else None, reason, n,
                    bound and decision != INDETERMINATE)
