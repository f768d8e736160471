"""The demo mission's client side (``ird_ros.apps.demo``): infer, plan twice, watch Rob, then the
rounds of questions, all through ``ird_ros.client.IrdClient`` (docs/spec.md sections 3, 4, 6, 7).

:class:`Mission` reads like the mission: the proxy, ``/ird/infer`` (the IRD posterior), the literal
and the IRD plan driven by Rob, the planner's risk map; with ``--queries N`` each round asks
``/ird/query``, waits for the designer's answer on ``/ird/queries`` and its re-sampled posterior,
and has Rob drive the new IRD plan. :class:`Results` fills as it goes, so Ctrl-C keeps what was done.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from typing import Any

import numpy as np

from ird_core.experiments import MAIN_BASELINE, MAIN_GRANULARITY, TrialSpec
from ird_core.worlds import evaluation
from ird_ros.apps.demo_rounds import Outcome, RoundResult, describe_counts, terrain_counts
from ird_ros.client import IrdClient, infer_request, plan_request, query_request
from ird_ros.graph import names

__all__ = ["Mission", "Results"]


@dataclasses.dataclass
class Results:
    """What the mission produced so far (filled as it goes, so Ctrl-C keeps what was done)."""

    outcomes: list[Outcome] = dataclasses.field(default_factory=list)
    risk: np.ndarray | None = None
    rounds: list[RoundResult] = dataclasses.field(default_factory=list)


class Mission:
    """The client side of the mission: infer, plan twice, watch Rob; then the rounds of questions."""

    def __init__(self, ird: IrdClient, args: argparse.Namespace, spec: TrialSpec, test_labels: np.ndarray,
                 results: Results) -> None:
        self.ird, self.args, self.spec, self.results = ird, args, spec, results
        self.test_labels = test_labels
        self.proxy: Any = None

    def run(self) -> None:
        self.ird.watch_rob(timeout=60)  # before any plan exists: /rob/status is a volatile stream
        self.ird.subscribe(names.TOPIC_RISK_MAP)
        self.proxy = self.ird.proxy(timeout=60)
        post = self.infer()
        self.results.outcomes.append(self.drive("literal", "literal", "none", ()))
        self.results.outcomes.append(self.drive(f"IRD {MAIN_GRANULARITY}", MAIN_GRANULARITY, MAIN_BASELINE,
                                                post.samples))
        self.results.risk = self.ird.risk_map()
        if self.args.queries:
            self.ask_questions()

    def inference_request(self) -> Any:
        """The world's own request for a world file (every training world), else the proxy on the
        published training map (latent_classifier: the proxy lives on the classified map)."""
        args, spec, proxy = self.args, self.spec, self.proxy
        if args.world is not None:
            request = self.ird.world_infer_request(timeout=60)
            request.beta, request.method = float(spec.beta), args.method
            request.num_samples, request.seed = int(spec.num_samples), int(args.seed)
            return request
        proxy_map = (self.ird.latest(names.TOPIC_TRAIN_PROXY_FEATURES, timeout=60)
                     if args.condition == "latent_classifier" else None)
        return infer_request(self.ird.latest(names.TOPIC_TRAIN_FEATURES, timeout=60),
                             (proxy.start_row, proxy.start_col), proxy.horizon, proxy.weights,
                             beta=spec.beta, method=args.method, num_samples=spec.num_samples, seed=args.seed,
                             proxy_map=proxy_map)

    def infer(self) -> Any:
        """``/ird/infer``; the posterior (exits the demo if the node refuses)."""
        t0 = time.monotonic()
        result = self.ird.infer(self.inference_request(), timeout=300)
        if not result.ok:
            raise SystemExit(f"/ird/infer failed: {result.message}")
        post = result.value
        print(f"/ird/infer: {post.samples.shape[0]} samples in {time.monotonic() - t0:.1f} s, "
              f"acceptance {post.acceptance_rate:.2f}, R-hat {post.r_hat_max:.3f}, ESS {post.ess_min:.0f}",
              flush=True)
        return post

    def drive(self, label: str, mode: str, baseline: str, weights: Any) -> Outcome:
        """``/ird/plan`` on the latest perceived test map (empty weights: the world's proxy for
        literal), then wait for Rob to finish it."""
        proxy = self.proxy
        request = plan_request((proxy.test_start_row, proxy.test_start_col), proxy.test_horizon, mode, baseline,
                               weights=weights, label=label)
        result = self.ird.plan(request, timeout=300)
        if not result.ok:
            raise SystemExit(f"/ird/plan ({label}) failed: {result.message}")
        plan = result.value
        print(f"/ird/plan {label}: objective {plan.objective:.3f}; Rob executes it...", flush=True)
        rob = self.ird.wait_for_rob(plan, timeout=120, label=f"the {label}")
        cells = list(plan.cells)
        return Outcome(label, cells, plan.objective, rob.touched_lava, rob.reached_target, rob.true_return,
                       evaluation.reaches_gold(self.test_labels, cells))

    def ask_questions(self) -> None:
        """``args.queries`` rounds (see :meth:`ask`), until one has nothing left to ask."""
        self.ird.subscribe(names.TOPIC_QUERIES, names.TOPIC_POSTERIOR)
        t_rounds = time.monotonic()
        for index in range(1, self.args.queries + 1):
            round_result = self.ask(index)
            if round_result is None:
                break
            self.results.rounds.append(round_result)
        print(f"{len(self.results.rounds)} round(s) (question, answer, re-sampling, new plan, Rob's drive) in "
              f"{time.monotonic() - t_rounds:.1f} s", flush=True)

    def ask(self, index: int) -> RoundResult | None:
        """One round: ``/ird/query``, the designer's answer (on ``/ird/queries``) and its re-sampled
        posterior, the planner's new risk map, a new IRD plan that Rob drives. None: nothing to ask."""
        args, ird, proxy = self.args, self.ird, self.proxy
        risk_count = len(ird.received(names.TOPIC_RISK_MAP))
        request = query_request((proxy.test_start_row, proxy.test_start_col), num_options=args.num_options,
                                strategy=args.strategy, seed=(args.seed + index) % 2**32)
        t0 = time.monotonic()
        result = ird.propose_query(request, timeout=300)
        if not result.ok:
            if result.field == "num_options":  # every sample plans the same few paths
                print(f"round {index}: nothing left to ask ({result.message})", flush=True)
                return None
            raise SystemExit(f"/ird/query failed: {result.message}")
        query = result.value
        counts = terrain_counts(self.test_labels, query.options)
        described = "; ".join(f"{k}: {describe_counts(c)}" for k, c in enumerate(counts))
        print(f"round {index}: query {query.query_id} in {time.monotonic() - t0:.1f} s, information gain "
              f"{query.information_gain:.3f} nats; options {described}; waiting for the {args.designer} "
              "designer...", flush=True)
        # A person takes as long as they take; the simulated designer answers within a re-sampling.
        record = ird.wait_for_answer(query.query_id, timeout=math.inf if args.designer == "web" else 300.0)
        post = ird.posterior_of(record, timeout=60)
        risk = ird.risk_map(after=risk_count)
        print(f"round {index}: option {record.chosen} chosen by {record.answered_by}; re-sampled posterior "
              f"({post.samples.shape[0]} samples, R-hat {post.r_hat_max:.3f}) {time.monotonic() - t0:.1f} s after "
              "the question", flush=True)
        plan = self.drive(f"IRD after {index}", MAIN_GRANULARITY, MAIN_BASELINE, post.samples)
        return RoundResult(index, query.query_id, query.information_gain, query.options, int(record.chosen),
                           str(record.answered_by), plan, counts, risk)
