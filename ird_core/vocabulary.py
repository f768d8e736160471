"""The project's vocabulary: every name that selects a behaviour, defined once as a ``StrEnum``.

Members are ``str`` subclasses, so they compare equal to the strings on the wire (ROS messages,
CSV columns, command-line options) and format as their value. The tuples beside each enum
(``METHODS``, ``MODES``, ...) list the plain values in the enum's order, for error messages
and ``argparse`` choices. Code that receives a name from outside converts it with
:func:`parse`, which refuses unknown names naming the field.
"""

from __future__ import annotations

from enum import StrEnum
from typing import TypeVar

__all__ = [
    "ZMethod",
    "PlanMode",
    "Baseline",
    "RiskStatistic",
    "ProxyCounts",
    "RiskMeasure",
    "QueryStrategy",
    "QueryKind",
    "Condition",
    "QueryEvent",
    "TerrainName",
    "METHODS",
    "MODES",
    "BASELINES",
    "STATISTICS",
    "PROXY_COUNTS",
    "RISK_MEASURES",
    "STRATEGIES",
    "QUERY_KINDS",
    "CONDITIONS",
    "ALL_CONDITIONS",
    "EVENTS",
    "TERRAIN_NAMES",
    "values",
    "parse",
]


class ZMethod(StrEnum):
    """How the IRD observation model's normaliser Z~(w) is approximated (docs/spec.md section 3)."""

    MAXENT_Z = "maxent_z"
    SAMPLE_Z = "sample_z"


class PlanMode(StrEnum):
    """What the planner optimises (docs/spec.md section 4): the proxy literally, or the worst case
    over posterior samples per step or per trajectory (the granularity)."""

    LITERAL = "literal"
    PER_STEP = "per_step"
    TRAJECTORY = "trajectory"


class Baseline(StrEnum):
    """The reward baseline subtracted per sample before the worst case (docs/spec.md section 4)."""

    NONE = "none"
    INITIAL_STATE = "initial_state"
    TRAINING_FEATURES = "training_features"
    LOG_Z = "log_z"


class RiskStatistic(StrEnum):
    """The spread of the samples' cell rewards that the risk map shows."""

    STD = "std"
    RANGE = "range"


class ProxyCounts(StrEnum):
    """How a reward's behaviour in a training MDP is summarised by the IRD observation model
    (docs/spec.md section 3): the feature counts of its optimal path (the paper's Sample-Z
    wording), or its MaxEnt expected counts at the designer's temperature."""

    OPTIMAL = "optimal"
    MAXENT = "maxent"


class RiskMeasure(StrEnum):
    """The statistic over posterior samples that a risk-averse plan maximises (docs/spec.md
    section 4): the worst sample, the conditional value at risk at level alpha (the mean of the
    worst alpha share; alpha = 1/K is the min, alpha = 1 the mean), or mean - lambda * sd."""

    MIN = "min"
    CVAR = "cvar"
    MEAN_SD = "mean_sd"


class QueryStrategy(StrEnum):
    """How the robot picks the question it asks the designer (docs/spec.md section 7)."""

    EVOI = "evoi"
    MAX_REGRET = "max_regret"
    INFO_GAIN = "info_gain"
    RANDOM = "random"


class QueryKind(StrEnum):
    """What the designer is asked to choose among (docs/spec.md section 7): paths on the query
    map, or the proxy rewards they might have written for the training map (Active IRD)."""

    PATHS = "paths"
    PROXIES = "proxies"


class Condition(StrEnum):
    """Lavaland's conditions (docs/spec.md section 5): the paper's four, then pot_of_gold."""

    SIDE_EFFECTS = "side_effects"
    REWARD_HACKING = "reward_hacking"
    LATENT_RAW = "latent_raw"
    LATENT_CLASSIFIER = "latent_classifier"
    POT_OF_GOLD = "pot_of_gold"


class QueryEvent(StrEnum):
    """What happened to a question: the robot proposed it, the designer answered it."""

    PROPOSED = "proposed"
    ANSWERED = "answered"


class TerrainName(StrEnum):
    """Terrain names, in the order of ``ird_core.worlds.terrain.Terrain``'s integer labels."""

    DIRT = "dirt"
    GRASS = "grass"
    TARGET = "target"
    LAVA = "lava"
    GOLD = "gold"


E = TypeVar("E", bound=StrEnum)


def values(enum: type[StrEnum]) -> tuple[str, ...]:
    """The members' plain string values, in definition order."""
    return tuple(member.value for member in enum)


def parse(enum: type[E], value: object, field: str) -> E:
    """``value`` as a member of ``enum``; a ``ValueError`` naming ``field`` and the choices if it
    is not one of them."""
    if isinstance(value, str):
        try:
            return enum(value)
        except ValueError:
            pass
    raise ValueError(f"{field}: expected one of {values(enum)}, got {value!r}")


METHODS: tuple[str, ...] = values(ZMethod)
MODES: tuple[str, ...] = values(PlanMode)
BASELINES: tuple[str, ...] = values(Baseline)
STATISTICS: tuple[str, ...] = values(RiskStatistic)
PROXY_COUNTS: tuple[str, ...] = values(ProxyCounts)
RISK_MEASURES: tuple[str, ...] = values(RiskMeasure)
STRATEGIES: tuple[str, ...] = values(QueryStrategy)
QUERY_KINDS: tuple[str, ...] = values(QueryKind)
ALL_CONDITIONS: tuple[str, ...] = values(Condition)
CONDITIONS: tuple[str, ...] = ALL_CONDITIONS[:4]
"""The paper's four conditions (every experiment iterates these); ``ALL_CONDITIONS`` adds pot_of_gold."""
EVENTS: tuple[str, ...] = values(QueryEvent)
TERRAIN_NAMES: tuple[str, ...] = values(TerrainName)
