"""The paper's experiments (Figure 4, the appendix factorial; docs/spec.md section 5) and the
designer-in-the-loop experiment (docs/spec.md section 7). Pure numpy/scipy, no ROS.

Modules: ``trials`` (one Lavaland trial, a pure function of its ``TrialSpec``), ``summaries``
(its aggregation), ``active`` (the designer-in-the-loop trial), ``statistics`` (intervals, paired
comparisons, the gap closed, shared by both), ``report`` / ``active_report`` (their csv,
markdown and figures), ``tables`` (how reports write numbers), ``parallel`` (process pool or
Dask map), ``progress`` (tqdm bars, imported only when drawn), ``cli`` / ``active_cli`` / ``scale_cli`` (the
command lines, ``main(argv) -> int``), ``posterior_terrain`` (the posterior's spread per terrain),
``scale`` (where IRD goes wrong on robot-sized maps), ``scale_timing`` (what a converged
posterior and a plan cost at a map size), ``provenance`` (which code produced a result). The
hypothesis spaces they compare live in :mod:`ird_core.hypothesis`.
"""

from __future__ import annotations

from ird_core.experiments.active import ActiveResult, ActiveSpec, ActiveSummary
from ird_core.experiments.statistics import (
    convergence,
    gap_closed,
    gap_share,
    group_by,
    paired_by_seed,
    paired_difference,
    paired_gap_closed,
    proportion,
    t_interval,
    wilson_interval,
)
from ird_core.experiments.summaries import RESULT_COLUMNS, CellSummary, aggregate
from ird_core.experiments.trials import (
    BASELINES,
    GRANULARITIES,
    MAIN_BASELINE,
    MAIN_GRANULARITY,
    QUICK,
    RUN_UNTIL_R_HAT,
    TRIAL_COLUMNS,
    Z_METHODS,
    SamplerSettings,
    TrialResult,
    TrialSpec,
    make_specs,
    run_trial,
    trial_instance,
    trial_seed,
)

__all__ = [
    "Z_METHODS",
    "RUN_UNTIL_R_HAT",
    "GRANULARITIES",
    "BASELINES",
    "MAIN_GRANULARITY",
    "MAIN_BASELINE",
    "SamplerSettings",
    "TrialSpec",
    "QUICK",
    "TrialResult",
    "CellSummary",
    "trial_seed",
    "trial_instance",
    "make_specs",
    "run_trial",
    "aggregate",
    "RESULT_COLUMNS",
    "TRIAL_COLUMNS",
    "ActiveSpec",
    "ActiveResult",
    "ActiveSummary",
    "group_by",
    "wilson_interval",
    "proportion",
    "t_interval",
    "convergence",
    "paired_by_seed",
    "paired_difference",
    "paired_gap_closed",
    "gap_share",
    "gap_closed",
]
