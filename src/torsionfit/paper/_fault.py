"""The worn unit of Fig. 19: the bundled small reducer's virtual bench with a worn mesh — the
gap grown and the mesh softer — measured with the same runs. SYNTHETIC, like every unit here."""

import dataclasses

from ..bench import Bench

#: wear: factor on the geometric gap β and on the mesh stiffness K
GAP_FACTOR = 1.5
STIFFNESS_FACTOR = 0.85


def worn_bench(bench: Bench, seed: int, gap_factor: float = GAP_FACTOR,
               stiffness_factor: float = STIFFNESS_FACTOR) -> Bench:
    """``bench`` with its truth's ``gap`` × ``gap_factor`` and ``stiffness`` × ``stiffness_factor``,
    its noise drawn with ``seed``, and a label saying so."""
    truth = dict(bench.truth)
    truth["gap"] = truth["gap"] * gap_factor
    truth["stiffness"] = truth["stiffness"] * stiffness_factor
    label = (f"{bench.label}; WORN unit: gap x{gap_factor:g}, mesh stiffness x{stiffness_factor:g} "
             f"(virtual bench, seed {seed})")
    name = f"{bench.reducer.name}-worn"
    return dataclasses.replace(bench, truth=truth, seed=seed, label=label,
                               reducer=dataclasses.replace(bench.reducer, name=name))
