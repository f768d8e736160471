"""The one record of the posterior sampler's keyword settings (docs/spec.md sections 3 and 7).

:class:`SamplerSettings` holds the keywords of :func:`ird_core.posterior.sample_posterior` /
:func:`ird_core.posterior.sample_joint_posterior` that callers tune (the experiments' per-method
recipes, the inference node's parameters); ``None`` means "the sampler's default".
:meth:`SamplerSettings.kwargs` is the mapping to pass: a ``None`` field is passed as ``None``
when ``None`` is the sampler's own default for that keyword (:data:`NONE_IS_DEFAULT`), and left
out otherwise, so an empty record is exactly the sampler's defaults.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from ird_core.posterior.run_until import RunUntil

__all__ = ["SamplerSettings", "NONE_IS_DEFAULT"]

#: The keywords whose default in ``sample_joint_posterior`` is ``None`` (passed even when unset).
NONE_IS_DEFAULT: tuple[str, ...] = (
    "warmup", "thin", "max_leapfrog", "warmup_max_leapfrog", "trajectory_length", "until_converged")


@dataclass(frozen=True)
class SamplerSettings:
    """The sampler's keyword settings; every field ``None`` = the sampler's default.

    Attributes:
        num_chains: parallel chains.
        warmup: warm-up iterations per chain.
        thin: keep every ``thin``-th draw (a fixed-length run of ``ceil(N / chains) * thin``).
        max_leapfrog: HMC's leapfrog steps per iteration after warm-up.
        kernel: one of ``ird_core.mcmc.KERNELS``.
        warmup_max_leapfrog, trajectory_length: HMC's warm-up step cap and trajectory length.
        num_proxy_samples: Sample-Z's ``N``.
        until_converged: extend the chains until converged (:class:`RunUntil`), or a fixed run.
    """

    num_chains: int | None = None
    warmup: int | None = None
    thin: int | None = None
    max_leapfrog: int | None = None
    kernel: str | None = None
    warmup_max_leapfrog: int | None = None
    trajectory_length: float | None = None
    num_proxy_samples: int | None = None
    until_converged: RunUntil | None = None

    def kwargs(self) -> dict[str, Any]:
        """The keyword arguments of ``sample_posterior`` / ``sample_joint_posterior``."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return {name: value for name, value in values.items() if value is not None or name in NONE_IS_DEFAULT}
