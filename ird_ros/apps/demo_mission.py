"""The demo mission's client side (``ird_ros.apps.demo``): two navigation goals, then the rounds of
questions, all through ``ird_ros.client.IrdClient`` (docs/spec.md sections 3, 4, 6, 7).

:class:`Mission` reads like the mission: the proxy, the literal goal and the IRD goal on the
navigator's action ``/ird/navigate`` (the first goal runs ``/ird/infer`` on the world's request, the
IRD goal plans per step against that posterior; Rob drives each plan to the end), the planner's risk
map; with ``--queries N`` each round asks
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

from ird_core import planning
from ird_core.experiments import MAIN_BASELINE, MAIN_GRANULARITY, TrialSpec
from ird_core.vocabulary import PlanMode
from ird_core.worlds import evaluation
from ird_ros.apps.demo_rounds import Outcome, RoundResult, describe_counts, terrain_counts
from ird_ros.bags.missions import drive_outcome
from ird_ros.client import IrdClient, plan_request, query_request
from ird_ros.client.navigation import CURRENT_POSTERIOR, NavigationFeedback, NavigationGoal, NavigationStatus
from ird_ros.conversions.grids import feature_grid_from_msg as grid_from_msg
from ird_ros.conversions.posterior import posterior_from_msg
from ird_ros.graph import names
from ird_ros.web.page_state import option_letter

__all__ = ["Mission", "Results"]


@dataclasses.dataclass
class Results:
    """What the mission produced so far (filled as it goes, so Ctrl-C keeps what was done)."""

    outcomes: list[Outcome] = dataclasses.field(default_factory=list)
    risk: np.ndarray | None = None  # the planner's risk map of the IRD plan's posterior (0..100)
    spread: np.ndarray | None = None  # that posterior's reward spread per cell (the rounds picture's unit)
    rounds: list[RoundResult] = dataclasses.field(default_factory=list)


class Mission:
    """The client side of the mission: the literal and the IRD goal; then the rounds of questions."""

    def __init__(self, ird: IrdClient, args: argparse.Namespace, spec: TrialSpec, test_labels: np.ndarray,
                 results: Results) -> None:
        self.ird, self.args, self.spec, self.results = ird, args, spec, results
        self.test_labels = test_labels
        self.proxy: Any = None

    def run(self) -> None:
        self.ird.watch_rob(timeout=60)  # before any plan exists: /rob/status is a volatile stream
        self.ird.subscribe(names.TOPIC_RISK_MAP, names.TOPIC_POSTERIOR)
        self.proxy = self.ird.proxy(timeout=60)
        # the first goal has the navigator run /ird/infer (the literal plan ignores the posterior);
        # the IRD goal plans against that posterior, the current one (method "")
        self.results.outcomes.append(self.navigate(self.goal("literal", PlanMode.LITERAL, self.args.method, "none")))
        self.results.outcomes.append(self.navigate(self.goal(f"IRD {MAIN_GRANULARITY}", MAIN_GRANULARITY,
                                                             CURRENT_POSTERIOR, MAIN_BASELINE)))
        self.results.risk = self.ird.risk_map()
        self.results.spread = self.spread(posterior_from_msg(self.ird.latest(names.TOPIC_POSTERIOR)))
        if self.args.queries:
            self.ask_questions()

    def goal(self, label: str, mode: str, method: str, baseline: str) -> NavigationGoal:
        """A goal for ``/ird/navigate`` with the demo's sampler settings (``method`` "": no inference)."""
        spec, args = self.spec, self.args
        return NavigationGoal(method=method, beta=float(spec.beta), num_samples=int(spec.num_samples),
                              seed=int(args.seed), mode=str(mode), baseline=str(baseline), label=label)

    def navigate(self, goal: NavigationGoal) -> Outcome:
        """``/ird/navigate``: the navigator infers (if asked), plans and has Rob drive the plan to the end;
        the ``/ird/infer`` line is printed once the goal's posterior is in (exits the demo if the goal fails)."""
        stages: dict[str, float] = {}
        posteriors = len(self.ird.received(names.TOPIC_POSTERIOR))
        t0 = time.monotonic()

        def on_feedback(feedback: NavigationFeedback) -> None:
            stage = str(feedback.stage)
            if stage in stages:
                return
            stages[stage] = time.monotonic() - t0  # the time each stage began
            if stage in ("planning", "driving") and goal.method and "infer line" not in stages:
                seconds = stages["planning"] - stages.get("inferring", 0.0)
                if self.print_posterior(posteriors, seconds, feedback, last_chance=stage == "driving"):
                    stages["infer line"] = seconds
            if stage == "driving":
                print(f"/ird/navigate {goal.label}: planned; Rob executes it...", flush=True)

        result = self.ird.navigate(goal, on_feedback=on_feedback, timeout=600)
        if result.status is not NavigationStatus.SUCCEEDED:
            raise SystemExit(f"/ird/navigate ({goal.label}) {result.status.name.lower()}: {result.message}")
        cells = [(int(r), int(c)) for r, c in result.cells]
        moves = sum(1 for a, b in zip(cells, cells[1:]) if a != b)
        did = drive_outcome(touched_lava=result.touched_lava, reached_target=result.reached_target, moves=moves)
        print(f"/ird/navigate {goal.label}: objective {result.objective:.3f}; {len(cells)} cells driven: {did}",
              flush=True)
        return Outcome(goal.label, cells, result.objective, bool(result.touched_lava), bool(result.reached_target),
                       float("nan") if result.true_return is None else float(result.true_return),
                       evaluation.reaches_gold(self.test_labels, cells))

    def spread(self, post: Any) -> np.ndarray | None:
        """The posterior's reward spread per cell on the world's test map (``planning.reward_spread``):
        the rounds picture's risk panels share this one unit (the planner's risk maps are each relative
        to their own largest spread). None when the test map's layers are not the posterior's features."""
        grid = grid_from_msg(self.ird.latest(names.TOPIC_TEST_FEATURES))
        if tuple(grid.layers) != tuple(post.feature_names):
            return None
        return planning.reward_spread(grid.features.astype(np.float64), post.samples)

    def print_posterior(self, after: int, seconds: float, feedback: NavigationFeedback, last_chance: bool) -> bool:
        """The posterior the navigator's ``/ird/infer`` published (beyond the ``after`` received before the
        goal); not in yet: nothing (False), or on the ``last_chance`` the feedback's summary of it."""
        received = self.ird.received(names.TOPIC_POSTERIOR)
        if len(received) <= after:
            if last_chance:
                print(f"/ird/infer: {feedback.posterior_summary} in {seconds:.1f} s", flush=True)
            return last_chance
        post = posterior_from_msg(received[-1])
        print(f"/ird/infer: {post.samples.shape[0]} samples in {seconds:.1f} s, acceptance "
              f"{post.acceptance_rate:.2f}, R-hat {post.r_hat_max:.3f}, ESS {post.ess_min:.0f}", flush=True)
        return True

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
        described = "; ".join(f"{option_letter(k)}: {describe_counts(c)}" for k, c in enumerate(counts))
        print(f"round {index}: query {query.query_id} in {time.monotonic() - t0:.1f} s, information gain "
              f"{query.information_gain:.3f} nats; options {described}; waiting for the {args.designer} "
              "designer...", flush=True)
        # A person takes as long as they take; the simulated designer answers within a re-sampling.
        record = ird.wait_for_answer(query.query_id, timeout=math.inf if args.designer == "web" else 300.0)
        post = ird.posterior_of(record, timeout=60)
        ird.risk_map(after=risk_count)  # the planner's new risk map is out
        print(f"round {index}: Option {option_letter(int(record.chosen))} chosen by {record.answered_by}; re-sampled posterior "
              f"({post.samples.shape[0]} samples, R-hat {post.r_hat_max:.3f}) {time.monotonic() - t0:.1f} s after "
              "the question", flush=True)
        plan = self.drive(f"IRD after {index}", MAIN_GRANULARITY, MAIN_BASELINE, post.samples)
        return RoundResult(index, query.query_id, query.information_gain, query.options, int(record.chosen),
                           str(record.answered_by), plan, counts, self.spread(post))
