"""The programs of the project, each a module with ``main(argv: list[str] | None = None) -> int``
(the scripts in ``scripts/`` and the console entry points call them): the demo mission
(``demo``; its client side in ``demo_mission``, its rounds of questions in ``demo_rounds``), a
minimal inference client (``call_inference``) and the experiments through the graph
(``experiments_via_ros``). Every program talks to the graph through ``ird_ros.client.IrdClient``."""
