"""IRD's hypothesis space: the features a candidate true reward is linear in (docs/spec.md section 2).

The paper's hypothesis space is the world's own features: one-hot terrains, or the latent
conditions' 50-d observations, the features Rob's sensors report. This package adds the two
non-linear spaces the experiments measure beside it, both still linear in their weights, so the
posterior, the samplers and the planners are unchanged:

- :mod:`ird_core.hypothesis.rff`: random Fourier features of an RBF kernel on the observations
  (latent conditions; approximately a Gaussian-process prior over cell rewards).
- :mod:`ird_core.hypothesis.novelty`: one more feature, *novel*, zero on every training cell and
  the training features' scale on test cells unlike every training cell.

:class:`HypothesisSpace` names a space and turns a world instance into it
(``HypothesisSpace.apply``): the experiments (``TrialSpec.hypothesis`` / ``novelty_feature``)
and the world node (parameters ``hypothesis``, ``rff_features``, ``novelty_feature``,
``novelty_value``) use the same record, so a graph and a trial with the same settings plan on the
same features. Only IRD's features change: the proxy (its features, weights, and so the literal
plan) stays the designer's, and the sensors' maps are what they were.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ird_core.hypothesis.novelty import NOVELTY_FEATURE, NOVELTY_VALUES, with_novelty_feature
from ird_core.hypothesis.rff import (
    DEFAULT_RFF_FEATURES,
    HYPOTHESES,
    RFF_CONDITIONS,
    FourierMap,
    hypothesis_instance,
    with_rff_hypothesis,
)
from ird_core.worlds import lavaland

__all__ = ["HypothesisSpace", "LINEAR", "HYPOTHESES", "NOVELTY_VALUES", "NOVELTY_FEATURE", "DEFAULT_RFF_FEATURES",
           "RFF_CONDITIONS", "FourierMap", "hypothesis_instance", "with_rff_hypothesis", "with_novelty_feature"]


@dataclass(frozen=True)
class HypothesisSpace:
    """A hypothesis space: the base features or random Fourier features, with or without *novel*.

    Attributes:
        kind: one of :data:`HYPOTHESES`: ``"linear"`` (the world's own features, the paper's) or
            ``"rff"`` (random Fourier features in the latent conditions; other conditions keep
            their one-hot features, on which a linear reward is already every terrain function).
        rff_features: ``D`` of the ``"rff"`` space (an integer >= 1; unused by ``"linear"``).
        novelty_feature: append the *novel* feature (after the random features, if any).
        novelty_value: its value on novel cells, one of :data:`NOVELTY_VALUES`.

    Raises ``ValueError`` naming the field.
    """

    kind: str = "linear"
    rff_features: int = DEFAULT_RFF_FEATURES
    novelty_feature: bool = False
    novelty_value: str = "feature_scale"

    def __post_init__(self) -> None:
        if self.kind not in HYPOTHESES:
            raise ValueError(f"hypothesis: must be one of {HYPOTHESES}, got {self.kind!r}")
        count = self.rff_features
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            raise ValueError(f"rff_features: must be an integer >= 1, got {count!r}")
        object.__setattr__(self, "rff_features", int(count))
        if not isinstance(self.novelty_feature, (bool, np.bool_)):
            raise ValueError(f"novelty_feature: expected a bool, got {self.novelty_feature!r}")
        object.__setattr__(self, "novelty_feature", bool(self.novelty_feature))
        if self.novelty_value not in NOVELTY_VALUES:
            raise ValueError(f"novelty_value: must be one of {NOVELTY_VALUES}, got {self.novelty_value!r}")

    @property
    def is_linear(self) -> bool:
        """True for the paper's space: the world's own features, nothing added."""
        return self.kind == "linear" and not self.novelty_feature

    def apply(self, inst: lavaland.LavalandInstance) -> lavaland.LavalandInstance:
        """``inst`` with its hypothesis features in this space (random features first, then
        *novel*); ``inst`` itself when :attr:`is_linear`. Deterministic: a function of ``inst``
        (the random features are seeded by ``inst.seed``)."""
        out = hypothesis_instance(inst, self.kind, self.rff_features)
        return with_novelty_feature(out, self.novelty_value) if self.novelty_feature else out

    def describe(self) -> str:
        """``linear``, ``rff (D = 100)``, ``linear + novel (feature_scale)``, ...: for logs and reports."""
        text = "linear" if self.kind == "linear" else f"rff (D = {self.rff_features})"
        return f"{text} + novel ({self.novelty_value})" if self.novelty_feature else text


#: The paper's hypothesis space (the default everywhere).
LINEAR = HypothesisSpace()
