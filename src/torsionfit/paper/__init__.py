"""Reproducing Cheng et al. 2023 on the bundled SYNTHETIC campaigns (``torsionfit paper``):
the published values and the paper's inconsistencies, Tables 4 and 6 by the paper's own
evaluation with model HDIs, the generalised polynomial H of Eqs. (26)–(28), the operating
grid, the worn unit of Fig. 19, every figure, ``tables.json`` and the comparison page."""

from ._choice import fit_with_fallback as fit_with_fallback, posterior_line as posterior_line
from ._checks import Inconsistency as Inconsistency, inconsistencies as inconsistencies
from ._document import paper_document as paper_document
from ._fault import worn_bench as worn_bench
from ._grid import (
    OperatingGrid as OperatingGrid,
    evaluate_grid as evaluate_grid,
    grid_axes as grid_axes,
    grid_bench as grid_bench,
    simulate_grid as simulate_grid,
)
from ._page import comparison_page as comparison_page
from ._polynomial import (
    PolynomialFit as PolynomialFit,
    bic as bic,
    design_matrix as design_matrix,
    fit_polynomial as fit_polynomial,
    select_polynomial as select_polynomial,
)
from ._posterior import (
    kd_draws as kd_draws,
    quasi_static_rate as quasi_static_rate,
    run_component_draws as run_component_draws,
    secant_draws as secant_draws,
)
from ._published import (
    CITATION as CITATION,
    PUBLISHED as PUBLISHED,
    SYNTHETIC_LABEL as SYNTHETIC_LABEL,
    PublishedValue as PublishedValue,
    published as published,
)
from ._reproduction import Reproduction as Reproduction, default_data_dir as default_data_dir, derived_seed as derived_seed
from ._run import (
    figure_script as figure_script,
    make_figures as make_figures,
    run_paper as run_paper,
    write_page as write_page,
)
from ._settings import FULL as FULL, QUICK as QUICK, PaperSettings as PaperSettings, paper_settings as paper_settings
from ._tables import reproduce_tables as reproduce_tables, reproduced_value as reproduced_value
