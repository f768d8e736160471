"""The ROS-free work behind the nodes: typed, validated jobs that run in worker processes and
the logic the rclpy shells in ``ird_ros.nodes`` call.

Modules (import from them; this package imports none, so a node loads only what it uses):
``inference`` (the posterior jobs of ``/ird/infer`` and ``/ird/answer``), ``inference_queries``
(the evidence of the current world and ``/ird/query``'s job), ``planning`` (``/ird/plan``'s job),
``rob_logic`` (Rob's plan execution and stop), ``navigation`` (the navigator's goal checks,
stages and Rob's drive), ``ground_truth`` (the ground-truth terrain as the core's
labels, for ``ird_core.worlds.evaluation``) and ``work`` (the work models that bound
``/ird/infer`` and ``/ird/query`` before they start).
"""
