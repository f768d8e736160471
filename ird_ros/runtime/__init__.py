"""What every node process runs on: start-up and clean shutdown (``node_main``), the managed
(lifecycle) node base with read-only and run-time parameters (``lifecycle``), parameter
tables (``node_params``), the guard around every callback (``guard``), and the worker processes
behind the services (``workers``: one job per worker, ``offload``: busy and failure answers)."""
