"""``ird``: one command for a running IRD graph, in place of the ``ros2`` CLI the pip wheels lack.

    ird graph [nodes|topics|services|actions]   # what runs in the domain (``ros2 node/topic/... list``)
    ird echo TOPIC [--once | -n N] [--field F]  # print a topic's messages (``ros2 topic echo``)
    ird navigate [--mode per_step ...]          # a NavigateIrd goal with feedback (``ros2 action send_goal``)
    ird infer [--from-world ...]                # /ird/infer once (``ird-infer``, ``ird_ros.apps.call_inference``)

Every verb joins the ROS domain given by ``--domain-id N`` (default: ``ROS_DOMAIN_ID``, else 0), the
one a launcher printed (``[launcher] ROS_DOMAIN_ID=N``), and prints it once on stderr with the line
a second shell runs to attach (stdout carries only the verb's output). Exit status: 0 done; 1 no
graph in the domain, or a goal or call that did not succeed; 2 bad input (an unknown topic or field,
a value the graph refuses: one line naming it); 130 Ctrl-C (``navigate`` cancels its goal first).

One module per verb (``graph``, ``echo``, ``navigate``, ``infer``), the shared parts in ``common``
(options, errors, the client), ``discovery`` (what the graph holds, waiting until it is complete)
and ``messages`` (a message as YAML, ``--field`` paths); the entry point is ``ird_ros.cli.main``.
"""
