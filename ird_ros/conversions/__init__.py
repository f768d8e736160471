"""Every numpy <-> message conversion; they refuse bad input with a ValueError naming the field."""

from __future__ import annotations

from ird_ros.conversions.geometry import (
    cell_center,
    grid_coordinates,
    point_cells,
)
from ird_ros.conversions.grids import (
    MAP_FRAME,
    UNKNOWN_CLASS,
    FeatureGridData,
    TerrainGridData,
    feature_grid_from_msg,
    feature_grid_to_msg,
    make_header,
    make_map_info,
    occupancy_grid_from_msg,
    occupancy_grid_to_msg,
    terrain_grid_from_msg,
    terrain_grid_to_msg,
)
from ird_ros.conversions.posterior import (
    R_HAT_CONVERGED,
    PosteriorData,
    cells_to_path,
    path_to_cells,
    posterior_from_msg,
    posterior_to_msg,
    weights_from_flat,
    weights_to_flat,
)
from ird_ros.conversions.queries import (
    options_to_paths,
    query_record_from_msg,
    query_record_to_msg,
)

__all__ = [
    "MAP_FRAME",
    "UNKNOWN_CLASS",
    "FeatureGridData",
    "TerrainGridData",
    "make_header",
    "make_map_info",
    "feature_grid_to_msg",
    "feature_grid_from_msg",
    "terrain_grid_to_msg",
    "terrain_grid_from_msg",
    "occupancy_grid_to_msg",
    "occupancy_grid_from_msg",
    "cell_center",
    "grid_coordinates",
    "point_cells",
    "options_to_paths",
    "query_record_to_msg",
    "query_record_from_msg",
    "R_HAT_CONVERGED",
    "PosteriorData",
    "posterior_to_msg",
    "posterior_from_msg",
    "cells_to_path",
    "path_to_cells",
    "weights_to_flat",
    "weights_from_flat",
]
