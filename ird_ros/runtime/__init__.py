"""What every node process runs on: start-up and clean shutdown (``node_main``), parameter
tables (``node_params``), and the worker pool behind the services (``offload``)."""
