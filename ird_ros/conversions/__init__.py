"""numpy <-> ROS message conversions: the only place where arrays become messages.

Import the package (``from ird_ros import conversions as conv``); ``conv.X`` is the one name of
each conversion. Modules: ``grids`` (FeatureGrid, TerrainGrid, OccupancyGrid, Header), ``paths``
(nav_msgs/Path <-> cells), ``posterior`` (RewardPosterior, flat weights), ``queries`` (the
designer conversation: ProposeQuery options, QueryRecord). Not exported here (import the module):
``sizes`` (request sizes from declared lengths, before decoding) and ``inference_requests``
(an ``/ird/infer`` request as its validated worker job). The cell geometry they build on is the
ROS-free :mod:`ird_ros.geometry` (exported here too).

Grid convention (docs/spec.md section 6): a map of H rows and W columns is a numpy array
indexed ``[row, col, ...]`` in C order; row 0 is the bottom row, x grows with the column
and y with the row, and the centre of cell ``(row, col)`` is at
``x = origin_x + (col + 0.5) * resolution``, ``y = origin_y + (row + 0.5) * resolution``
in frame ``map``.

Every ``*_from_msg`` / ``*_to_msg`` function validates its input and raises
``ValueError`` with a message that starts with the offending field, e.g.
``"FeatureGrid.data: expected 4500 values (H=15 x W=15 x d=20), got 4499"``. Functions
that read a message take ``field=`` to name it as the caller sees it (a service node
passes ``field="training_map"`` so the message says ``training_map.data: ...``). Names from
the vocabulary (method, mode, baseline, strategy, query event) are read into
``ird_core.vocabulary`` enums and unknown ones refused naming the field.

Large arrays use the fast paths: ``array.array(typecode, arr.tobytes())`` to fill a
message field and ``np.frombuffer`` to read one (the read arrays are copies, so they
stay valid and writable after the message is gone).
"""

from __future__ import annotations

from ird_ros.conversions.grids import (
    MAP_FRAME,
    UNKNOWN_CLASS,
    FeatureGridData,
    TerrainGridData,
    feature_grid_from_msg,
    feature_grid_to_msg,
    first_with_layers,
    make_header,
    make_map_info,
    now_stamp,
    occupancy_grid_from_msg,
    occupancy_grid_to_msg,
    terrain_grid_from_msg,
    terrain_grid_to_msg,
)
from ird_ros.conversions.paths import cells_to_path, path_to_cells
from ird_ros.conversions.posterior import (
    PosteriorData,
    posterior_from_msg,
    posterior_to_msg,
    weights_from_flat,
    weights_to_flat,
)
from ird_ros.conversions.queries import options_to_paths, query_record_from_msg, query_record_to_msg
from ird_ros.geometry import cell_center, grid_coordinates, point_cells

__all__ = [
    "MAP_FRAME",
    "UNKNOWN_CLASS",
    "FeatureGridData",
    "TerrainGridData",
    "make_header",
    "make_map_info",
    "now_stamp",
    "first_with_layers",
    "feature_grid_to_msg",
    "feature_grid_from_msg",
    "terrain_grid_to_msg",
    "terrain_grid_from_msg",
    "occupancy_grid_to_msg",
    "occupancy_grid_from_msg",
    "cell_center",
    "grid_coordinates",
    "point_cells",
    "cells_to_path",
    "path_to_cells",
    "options_to_paths",
    "query_record_to_msg",
    "query_record_from_msg",
    "PosteriorData",
    "posterior_to_msg",
    "posterior_from_msg",
    "weights_to_flat",
    "weights_from_flat",
]
