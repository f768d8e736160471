"""One client of a running IRD graph (docs/spec.md section 6): :class:`IrdClient`, its typed results,
and request builders, built on ``ird_ros.waits`` (discovery, messages, services; no sleeps)."""

from __future__ import annotations

from ird_ros.client.ird_client import (
    ALL_SERVICES,
    ClientTimeout,
    GraphNotFound,
    IrdClient,
    PendingCall,
    domain_hint,
)
from ird_ros.client.navigation import (
    NavigationFeedback,
    NavigationGoal,
    NavigationHandle,
    NavigationResult,
    NavigationStatus,
)
from ird_ros.client.requests import infer_request, plan_request, query_request
from ird_ros.client.results import (
    CallFailed,
    CallResult,
    CallStatus,
    Plan,
    Query,
    RobDrive,
    WorldMessages,
    classify_answer,
)

__all__ = [
    "IrdClient",
    "NavigationGoal",
    "NavigationFeedback",
    "NavigationResult",
    "NavigationStatus",
    "NavigationHandle",
    "PendingCall",
    "ClientTimeout",
    "GraphNotFound",
    "ALL_SERVICES",
    "domain_hint",
    "CallStatus",
    "CallResult",
    "CallFailed",
    "classify_answer",
    "Plan",
    "Query",
    "RobDrive",
    "WorldMessages",
    "infer_request",
    "plan_request",
    "query_request",
]
