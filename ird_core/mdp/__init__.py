"""Grid MDPs and exact maximum-entropy trajectory inference on them (docs/spec.md sections 1-2)."""

from __future__ import annotations

from ird_core.mdp.grid import (
    MOVES,
    GridMDP,
    cell_rewards,
    path_features,
    path_return,
    successor_table,
    validate_path,
)
from ird_core.mdp.optimal_paths import optimal_feature_counts, optimal_paths, optimal_returns
from ird_core.mdp.passes import (
    expected_visitation,
    feature_expectations,
    hard_values,
    log_partition,
    log_partition_and_feature_expectations,
    optimal_path,
    soft_values,
    warm_up,
)

__all__ = [
    "MOVES",
    "GridMDP",
    "cell_rewards",
    "soft_values",
    "log_partition",
    "expected_visitation",
    "feature_expectations",
    "hard_values",
    "optimal_path",
    "optimal_paths",
    "optimal_feature_counts",
    "optimal_returns",
    "successor_table",
    "path_features",
    "path_return",
    "validate_path",
    "warm_up",
    "log_partition_and_feature_expectations",
]
