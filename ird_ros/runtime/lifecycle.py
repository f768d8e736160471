"""Managed (lifecycle) nodes, the Nav2 convention: every graph node is an ``rclpy.lifecycle`` node.

``ManagedNode`` is a :class:`~ird_ros.runtime.guard.GuardedNode` and an ``rclpy.lifecycle``
node (``LifecycleNodeMixin``: the services ``/<node>/change_state``, ``/<node>/get_state``,
``/<node>/get_available_states``, ``/<node>/get_available_transitions`` and the
``/<node>/transition_event`` topic). A subclass names its parameter table (``PARAMETERS``) and
writes :meth:`ManagedNode.configure` (what its constructor used to do), optionally
:meth:`~ManagedNode.activate`, :meth:`~ManagedNode.deactivate`, :meth:`~ManagedNode.release`
and :meth:`~ManagedNode.apply_parameters`. The states:

- **unconfigured** (after the constructor): the parameters are declared, nothing else exists
  but the lifecycle and parameter services. Run-time parameters may be set.
- **configure** reads the parameters, checks their allowed values and calls ``configure(p)``,
  which creates the publishers (lifecycle publishers: they publish only while active),
  subscriptions, services, timers, action servers and worker pools. A bad parameter (or any
  other error) fails the transition: the reason is logged as ``configure failed: <reason>`` and
  kept in ``transition_error``, whatever was created is destroyed, the node stays unconfigured.
- **inactive**: subscriptions run (an inactive node keeps its latched inputs up to date, so
  activation is immediate) but nothing leaves the node: publishers drop their messages, the
  node's timers are cancelled, every service of its own answers ``success: false`` naming the
  state, the navigator rejects goals, the designer answers no question.
- **activate** enables the publishers, restarts the timers and calls ``activate()`` (the world
  publishes its world, perception its classification, ...); ``<name> ready`` is logged.
- **deactivate** calls ``deactivate()``, cancels the timers, disables the publishers.
- **cleanup** calls ``release()`` (worker pools, web servers, bags) and destroys everything
  ``configure`` created; the node is unconfigured again and can be configured anew.
- **shutdown** (from any primary state; ``run_node`` triggers it on SIGINT/SIGTERM) deactivates
  and cleans up what is still there; the node is finalized.

Parameters: each is read-only (``read_only`` in its descriptor, rclpy refuses a change with
"Trying to set a read-only parameter") unless its ``Param`` says ``runtime=True``. A run-time
parameter set while the node is configured is checked (allowed values) and handed to
``apply_parameters(p, changed)`` inside the ``on_set_parameters`` callback: it validates the
whole new set, raising ``ValueError`` (the set is refused with that reason, nothing changed)
or applies it. Set while unconfigured, the value is used by the next ``configure``.

``autostart`` (read-only, default true): ``run_node`` configures and activates the node itself
(a node started on its own, ``python -m ird_ros.nodes.world``, serves at once); the launcher
passes ``autostart:=false`` and drives the transitions through the lifecycle services.
"""

from __future__ import annotations

import inspect
from typing import Any, Callable, ClassVar, Mapping

from rclpy.lifecycle import LifecycleNodeMixin, LifecycleState, TransitionCallbackReturn

from ird_ros.runtime.guard import GuardedNode, guard_service, is_guarded
from ird_ros.runtime.node_main import StartupError, declare, start_up
from ird_ros.runtime.node_params import Param, check_choices, declare_all, read_all

__all__ = ["ManagedNode", "TransitionCallbackReturn", "start_up", "AUTOSTART"]

AUTOSTART = "autostart"

_KINDS = ("publishers", "subscriptions", "services", "clients", "timers", "waitables")


class ManagedNode(LifecycleNodeMixin, GuardedNode):
    """A guarded lifecycle node (module doc). ``params`` holds the parameters' current values."""

    PARAMETERS: ClassVar[Mapping[str, Param]] = {}

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        self._configuring = False
        self._active = False
        self._created: dict[str, list[Any]] = {}
        self._own_timers: list[Any] = []
        GuardedNode.__init__(self, node_name, **kwargs)
        LifecycleNodeMixin.__init__(self)
        for service in self.services:  # the lifecycle services, created without create_service
            if not is_guarded(service.callback):
                service.callback = guard_service(service.callback, self.get_logger(), service.srv_name)
        self.autostart = bool(declare(self, AUTOSTART, True, "Configure and activate at start-up (false: wait "
                                      "for a lifecycle manager, e.g. the launcher)", read_only=True))
        self.params: dict[str, Any] = declare_all(self, self.PARAMETERS, check=False)
        self.transition_error = ""
        self.add_on_set_parameters_callback(self._on_set_parameters)

    # ------------------------------------------------------------------ state

    @property
    def lifecycle_state(self) -> str:
        """The state's label: unconfigured, inactive, active, finalized or a transition's."""
        return str(self._state_machine.current_state[1])

    @property
    def is_active(self) -> bool:
        """Active, or activating (``activate()`` runs as if active: it publishes)."""
        return self._active

    @property
    def is_configured(self) -> bool:
        return bool(self._created)

    # ------------------------------------------------------------------ subclass hooks

    def configure(self, p: dict[str, Any]) -> None:
        """Create the node's resources from its parameters ``p`` (raise to fail the transition)."""

    def activate(self) -> None:
        """Start serving (publishers are already enabled): e.g. publish what is known."""

    def deactivate(self) -> None:
        """Stop what ``activate`` started (timers and publishers are handled here)."""

    def release(self) -> None:
        """Free what ``configure`` acquired besides ROS entities (worker pools, servers, files);
        safe to call on a partly configured node."""

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        """Apply run-time parameters ``changed`` (``p`` holds all values); raise ``ValueError``
        to refuse, before changing anything."""

    # ------------------------------------------------------------------ entities

    def create_publisher(self, *args: Any, **kwargs: Any) -> Any:
        if self._configuring:  # messages flow only while active
            return self.create_lifecycle_publisher(*args, **kwargs)
        return super().create_publisher(*args, **kwargs)

    def create_service(self, srv_type: Any, srv_name: str, callback: Callable, **kwargs: Any) -> Any:
        if self._configuring:
            callback = self._when_active(callback, srv_name)
        return super().create_service(srv_type, srv_name, callback, **kwargs)

    def _when_active(self, callback: Callable, srv_name: str) -> Callable:
        """``callback`` refusing requests (``success: false``, through the guard) unless active."""
        def refuse() -> None:
            if not self.is_active:
                raise ValueError(f"{self.get_name()} is {self.lifecycle_state}, not active: {srv_name} is not served")

        if inspect.iscoroutinefunction(callback):
            async def gated_async(request: Any, response: Any) -> Any:
                refuse()
                return await callback(request, response)
            return gated_async

        def gated(request: Any, response: Any) -> Any:
            refuse()
            return callback(request, response)
        return gated

    def _snapshot(self) -> dict[str, set[int]]:
        return {kind: {id(e) for e in getattr(self, kind)} for kind in _KINDS}  # rclpy's generators

    def _since(self, before: dict[str, set[int]]) -> dict[str, list[Any]]:
        return {kind: [e for e in getattr(self, kind) if id(e) not in before[kind]] for kind in _KINDS}

    def _destroy(self, created: Mapping[str, list[Any]]) -> None:
        for timer in created.get("timers", []):
            self.destroy_timer(timer)
        for waitable in created.get("waitables", []):
            waitable.destroy()  # an action server removes itself from the node
        for service in created.get("services", []):
            self.destroy_service(service)
        for client in created.get("clients", []):
            self.destroy_client(client)
        for sub in created.get("subscriptions", []):
            self.destroy_subscription(sub)
        for pub in created.get("publishers", []):
            self.destroy_lifecycle_publisher(pub)

    # ------------------------------------------------------------------ transitions

    def read_parameters(self) -> dict[str, Any]:
        """The parameters' current values, their allowed values checked (``StartupError``)."""
        return read_all(self, self.PARAMETERS)

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        before = self._snapshot()
        self._configuring = True
        try:
            self.params = self.read_parameters()
            self.configure(dict(self.params))
        except Exception as exc:  # noqa: BLE001 - any error fails the transition, with its reason
            self._configuring = False
            return self._failed("configure", exc, lambda: self._undo(self._since(before)))
        self._configuring = False
        self._created = self._since(before)
        self._own_timers = list(self._created["timers"])
        for timer in self._own_timers:
            timer.cancel()
        self.transition_error = ""
        return TransitionCallbackReturn.SUCCESS

    def _undo(self, created: Mapping[str, list[Any]]) -> None:
        try:
            self.release()
        finally:
            self._destroy(created)

    def _failed(self, what: str, exc: BaseException, undo: Callable[[], None]) -> TransitionCallbackReturn:
        reason = str(exc) if isinstance(exc, (StartupError, ValueError)) else f"{type(exc).__name__}: {exc}"
        self.transition_error = f"{what} failed: {reason}"
        self.get_logger().error(self.transition_error)
        try:
            undo()
        except Exception as undo_exc:  # noqa: BLE001 - the failure above is what matters
            self.get_logger().error(f"undoing the failed {what}: {type(undo_exc).__name__}: {undo_exc}")
        return TransitionCallbackReturn.FAILURE

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        super().on_activate(state)  # enables the lifecycle publishers
        for timer in self._own_timers:
            timer.reset()
        self._active = True
        try:
            self.activate()
        except Exception as exc:  # noqa: BLE001
            return self._failed("activate", exc, lambda: self._stop(state))
        self.transition_error = ""
        self.get_logger().info(f"{self.get_name()} ready")
        return TransitionCallbackReturn.SUCCESS

    def _stop(self, state: LifecycleState) -> None:
        self._active = False
        for timer in self._own_timers:
            timer.cancel()
        super().on_deactivate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self.deactivate()
        finally:
            self._stop(state)
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        created, self._created, self._own_timers = self._created, {}, []
        self._undo(created)
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        if state.label == "active":
            self.on_deactivate(state)
        if self._created:
            self.on_cleanup(state)
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.on_shutdown(state)
        return TransitionCallbackReturn.SUCCESS

    def destroy_node(self) -> None:
        """Destroy the node and leave the graph now, whoever still holds this Python object.

        rclpy's ``LifecycleNode`` keeps its state machine, which holds the rcl node, until the
        object is garbage-collected: a destroyed node stayed in the graph (its lifecycle services
        listed under its name) and kept its context's participant alive. Seen in the test suite,
        where pytest keeps fixture values: a later test leasing the same domain ID found a second
        ``/world`` whose services a by-name graph query read. The state machine is destroyed here.
        """
        if self._created:  # not shut down through the lifecycle (e.g. a test's own executor)
            created, self._created = self._created, {}
            try:
                self._undo(created)
            except Exception:  # noqa: BLE001 - destroying anyway
                pass
        super().destroy_node()
        machine = getattr(self, "_state_machine", None)
        if machine is not None:
            machine.destroy_when_not_in_use()

    # ------------------------------------------------------------------ parameters

    def _on_set_parameters(self, parameters: list[Any]) -> Any:
        from rcl_interfaces.msg import SetParametersResult

        changes = {p.name: p.value for p in parameters if p.name in self.PARAMETERS}
        if not changes:
            return SetParametersResult(successful=True)
        candidate = {**self.params, **changes}
        try:
            for name, value in changes.items():
                check_choices(name, self.PARAMETERS[name], value)
            if self._created and not self._configuring:
                self.apply_parameters(dict(candidate), set(changes))
        except (ValueError, StartupError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.params = candidate
        return SetParametersResult(successful=True)
