"""Worlds: terrain maps, the Gaussian observation model, Lavaland instances, world files.

Worlds never import the posterior: they describe maps, proxies and the true reward; the
posterior package builds its observations from them (``ird_core.posterior.proxy_observations``,
docs/spec.md section 5).

Modules: ``terrain`` (labels and the seeded map sampler), ``observations`` (Gaussian cell
observations and the safe-terrain classifier), ``lavaland`` (the paper's conditions and
pot_of_gold), ``evaluation`` (a path's true return and outcomes), ``world_file`` (worlds from
YAML + PNG files; its value readers in ``file_values``), ``export`` (the ``ird-export-world``
command line: a generated instance as a world file).
"""
