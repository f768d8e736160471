"""The latent-reward observation model of Lavaland and the designer's safe-terrain classifier.

In the paper's latent-reward conditions the robot does not see terrain labels: each terrain
``k`` induces a Gaussian ``N(mu_k, Sigma_k)`` over ``D``-dimensional observations of a cell
(``D = 50``), and the designer only ever saw the safe terrains (dirt, grass, target).

Observation model (:func:`make_observation_model`, every number is a keyword default):

* Safe means: the vertices of an equilateral triangle of side ``SAFE_SEPARATION = 6.0`` centred
  on the origin, in a uniformly random 2-plane of R^D (``(6 / sqrt 2) q_k`` for orthonormal
  ``q_k``, minus their centroid). "Close-ish": a few noise standard deviations apart, so the
  classes are distinct but a linear read-out of them is noisy. Why 6 and not less: the
  latent_raw proxy is a least-squares regression on noisy samples, whose fitted values at the
  class means shrink towards the grand mean as the classes overlap; at side 6 they stay close to
  the intended (0.1, -0.2, 1).
* Lava mean: ``LAVA_DISTANCE = 15.0`` from the safe centroid (the origin) in a uniformly random
  direction, hence at least ``15 - 6 / sqrt 3 = 11.54`` from every safe mean (typically close to
  15, since a random direction is nearly orthogonal to the safe plane): more than twice the safe
  separation. Its direction, not only its distance, is random, so a linear
  reward fitted on safe data extrapolates to an arbitrary value on lava.
* Covariances: ``Sigma_k = Q_k diag(e_k) Q_k^T`` with a Haar-random rotation ``Q_k`` and
  eigenvalues ``e_k ~ U(0.5, 1.5)`` per terrain (``EIGENVALUE_RANGE``): unit-ish noise in every
  direction, a different shape per terrain.

Classifier (:class:`TerrainClassifier`, :func:`fit_classifier`): quadratic discriminant
analysis (one Gaussian per safe class, each with its own covariance) fitted by maximum
likelihood (sample mean, unbiased sample covariance plus a ``1e-6 * mean variance`` ridge) on
``samples_per_class = 1000`` draws of each safe terrain, equal class priors (the training set is
balanced). QDA rather than LDA because the generating classes really do have different
covariances: QDA is the Bayes classifier of this model, LDA is not.

Novelty: the chi2 surprise of the nearest safe class, ``-log P(chi2_D >= min_c m_c(x))`` in
nats, where ``m_c`` is the squared Mahalanobis distance under the fitted class ``c``.

The classifier never saw lava, so it calls most lava samples some safe class with high
probability: it is confidently wrong, while the novelty separates lava from the safe terrains.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.special import logsumexp

from ird_core.worlds.terrain import SAFE_TERRAINS, Terrain, as_generator

__all__ = [
    "DEFAULT_DIM",
    "NUM_OBSERVED_TERRAINS",
    "SAFE_SEPARATION",
    "LAVA_DISTANCE",
    "EIGENVALUE_RANGE",
    "ObservationModel",
    "make_observation_model",
    "sample_observations",
    "TerrainClassifier",
    "fit_classifier",
]

DEFAULT_DIM: int = 50
SAFE_SEPARATION: float = 6.0
LAVA_DISTANCE: float = 15.0
EIGENVALUE_RANGE: tuple[float, float] = (0.5, 1.5)
_RIDGE: float = 1e-6
# The terrains with an observation Gaussian (labels 0..3): the latent conditions have no gold,
# and a fixed count keeps every model's random draws independent of later terrains.
NUM_OBSERVED_TERRAINS: int = 4


def _random_rotation(dim: int, rng: np.random.Generator) -> np.ndarray:
    """(dim, dim) Haar-distributed orthogonal matrix (QR of a Gaussian, sign-corrected)."""
    q, r = np.linalg.qr(rng.standard_normal((dim, dim)))
    return q * np.sign(np.diag(r))


@dataclasses.dataclass(frozen=True, eq=False)
class ObservationModel:
    """Per-terrain Gaussians over ``D``-dimensional cell observations.

    Attributes:
        means: (4, D) indexed by :class:`Terrain`.
        covariances: (4, D, D) symmetric positive definite, indexed by :class:`Terrain`.
        cholesky: (4, D, D) lower Cholesky factors (derived, not an init argument).
    """

    means: np.ndarray
    covariances: np.ndarray
    cholesky: np.ndarray = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        means = np.array(self.means, dtype=np.float64)
        covariances = np.array(self.covariances, dtype=np.float64)
        if means.ndim != 2 or means.shape[0] != NUM_OBSERVED_TERRAINS or means.shape[1] < 1:
            raise ValueError(f"means must have shape (4, D), got {means.shape}")
        dim = means.shape[1]
        if covariances.shape != (NUM_OBSERVED_TERRAINS, dim, dim):
            raise ValueError(
                f"covariances must have shape (4, {dim}, {dim}), got {covariances.shape}"
            )
        if not (np.all(np.isfinite(means)) and np.all(np.isfinite(covariances))):
            raise ValueError("means and covariances must be finite")
        if not np.allclose(covariances, np.swapaxes(covariances, 1, 2), atol=1e-10):
            raise ValueError("covariances must be symmetric")
        try:
            cholesky = np.linalg.cholesky(covariances)
        except np.linalg.LinAlgError as exc:
            raise ValueError("covariances must be positive definite") from exc
        for array in (means, covariances, cholesky):
            array.setflags(write=False)
        object.__setattr__(self, "means", means)
        object.__setattr__(self, "covariances", covariances)
        object.__setattr__(self, "cholesky", cholesky)

    @property
    def dim(self) -> int:
        return int(self.means.shape[1])


def make_observation_model(
    dim: int,
    seed: int | np.random.Generator,
    *,
    safe_separation: float = SAFE_SEPARATION,
    lava_distance: float = LAVA_DISTANCE,
    eigenvalue_range: tuple[float, float] = EIGENVALUE_RANGE,
) -> ObservationModel:
    """Build the seeded observation model described in the module docstring.

    Args:
        dim: observation dimension D (>= 3, so the safe triangle and the lava offset fit);
            the paper's and our default is :data:`DEFAULT_DIM` = 50.
        seed: int seed or numpy Generator.
        safe_separation: pairwise distance of the three safe means (> 0).
        lava_distance: distance of the lava mean from the safe centroid; must exceed the safe
            circumradius ``safe_separation / sqrt 3`` so lava is away from every safe mean.
        eigenvalue_range: (low, high) of the uniform covariance eigenvalues, 0 < low <= high.

    Returns:
        An :class:`ObservationModel` with D = ``dim``.
    """
    if not isinstance(dim, (int, np.integer)) or dim < 3:
        raise ValueError(f"dim must be an integer >= 3, got {dim!r}")
    if not np.isfinite(safe_separation) or safe_separation <= 0:
        raise ValueError(f"safe_separation must be > 0, got {safe_separation!r}")
    circumradius = safe_separation / np.sqrt(3.0)
    if not np.isfinite(lava_distance) or lava_distance <= circumradius:
        raise ValueError(
            f"lava_distance must exceed the safe circumradius {circumradius:.3f}, "
            f"got {lava_distance!r}"
        )
    low, high = eigenvalue_range
    if not (0 < low <= high and np.isfinite(high)):
        raise ValueError(f"eigenvalue_range must satisfy 0 < low <= high, got {eigenvalue_range}")
    rng = as_generator(seed)
    dim = int(dim)

    # Three orthonormal vectors scaled by s / sqrt 2 are pairwise s apart; centre them.
    basis = _random_rotation(dim, rng)[:, :3].T
    safe = basis * (safe_separation / np.sqrt(2.0))
    safe -= safe.mean(axis=0)
    direction = rng.standard_normal(dim)
    lava = lava_distance * direction / np.linalg.norm(direction)
    means = np.zeros((NUM_OBSERVED_TERRAINS, dim))
    means[list(SAFE_TERRAINS)] = safe
    means[Terrain.LAVA] = lava

    covariances = np.empty((NUM_OBSERVED_TERRAINS, dim, dim))
    for k in range(NUM_OBSERVED_TERRAINS):  # four terrains, not cells
        rotation = _random_rotation(dim, rng)
        eigenvalues = rng.uniform(low, high, size=dim)
        cov = (rotation * eigenvalues) @ rotation.T
        covariances[k] = 0.5 * (cov + cov.T)
    return ObservationModel(means=means, covariances=covariances)


def sample_observations(
    model: ObservationModel, labels: np.ndarray, seed: int | np.random.Generator
) -> np.ndarray:
    """Draw one observation per cell from its terrain's Gaussian.

    Args:
        model: the observation model.
        labels: (...,) integer :class:`Terrain` labels, e.g. an (H, W) map.
        seed: int seed or numpy Generator.

    Returns:
        (..., D) float64 observations.
    """
    labels = np.asarray(labels)
    if not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"labels must hold integer Terrain labels, got dtype {labels.dtype}")
    if labels.size and (labels.min() < 0 or labels.max() >= NUM_OBSERVED_TERRAINS):
        raise ValueError(f"labels holds values outside 0..{NUM_OBSERVED_TERRAINS - 1}")
    rng = as_generator(seed)
    noise = rng.standard_normal(labels.shape + (model.dim,))
    out = np.empty_like(noise)
    for k in range(NUM_OBSERVED_TERRAINS):  # four terrains, each vectorised over its cells
        mask = labels == k
        out[mask] = model.means[k] + noise[mask] @ model.cholesky[k].T
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class TerrainClassifier:
    """Gaussian class-conditional (QDA) classifier of the safe terrains dirt, grass, target.

    Class ``c`` is :class:`Terrain` ``c`` for c in 0..2, so predictions are terrain labels.
    The classifier has no lava class: it cannot know lava, and labels it as some safe class.

    Attributes:
        means: (3, D) fitted class means.
        covariances: (3, D, D) fitted class covariances.
        log_priors: (3,) log class priors (equal: the training set is balanced).
        whitening: (3, D, D) inverse lower Cholesky factors ``L_c^{-1}`` (derived).
        log_dets: (3,) log-determinants of the covariances (derived).
    """

    means: np.ndarray
    covariances: np.ndarray
    log_priors: np.ndarray
    whitening: np.ndarray = dataclasses.field(init=False, repr=False)
    log_dets: np.ndarray = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        means = np.array(self.means, dtype=np.float64)
        covariances = np.array(self.covariances, dtype=np.float64)
        log_priors = np.array(self.log_priors, dtype=np.float64)
        num_classes = len(SAFE_TERRAINS)
        if means.ndim != 2 or means.shape[0] != num_classes:
            raise ValueError(f"means must have shape (3, D), got {means.shape}")
        dim = means.shape[1]
        if covariances.shape != (num_classes, dim, dim):
            raise ValueError(f"covariances must have shape (3, {dim}, {dim}), got {covariances.shape}")
        if log_priors.shape != (num_classes,) or not np.all(np.isfinite(log_priors)):
            raise ValueError(f"log_priors must be 3 finite values, got {log_priors}")
        try:
            cholesky = np.linalg.cholesky(covariances)
        except np.linalg.LinAlgError as exc:
            raise ValueError("covariances must be positive definite") from exc
        whitening = np.linalg.inv(cholesky)
        log_dets = 2.0 * np.log(np.diagonal(cholesky, axis1=1, axis2=2)).sum(axis=1)
        for array in (means, covariances, log_priors, whitening, log_dets):
            array.setflags(write=False)
        object.__setattr__(self, "means", means)
        object.__setattr__(self, "covariances", covariances)
        object.__setattr__(self, "log_priors", log_priors)
        object.__setattr__(self, "whitening", whitening)
        object.__setattr__(self, "log_dets", log_dets)

    @property
    def dim(self) -> int:
        return int(self.means.shape[1])

    def _check(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        if obs.ndim < 1 or obs.shape[-1] != self.dim:
            raise ValueError(f"obs must have shape (..., {self.dim}), got {obs.shape}")
        return obs

    def mahalanobis_sq(self, obs: np.ndarray) -> np.ndarray:
        """Squared Mahalanobis distance to each fitted class: (..., D) -> (..., 3)."""
        obs = self._check(obs)
        centred = obs[..., None, :] - self.means  # (..., 3, D)
        whitened = np.einsum("cij,...cj->...ci", self.whitening, centred)
        return np.sum(whitened**2, axis=-1)

    def log_joint(self, obs: np.ndarray) -> np.ndarray:
        """``log p(obs, class)`` for each class: (..., D) -> (..., 3)."""
        distance = self.mahalanobis_sq(obs)
        log_norm = 0.5 * (self.dim * np.log(2.0 * np.pi) + self.log_dets)
        return self.log_priors - log_norm - 0.5 * distance

    def predict_proba(self, obs: np.ndarray) -> np.ndarray:
        """Class posteriors [dirt, grass, target]: (..., D) -> (..., 3), rows sum to 1."""
        joint = self.log_joint(obs)
        return np.exp(joint - logsumexp(joint, axis=-1, keepdims=True))

    def predict(self, obs: np.ndarray) -> np.ndarray:
        """Most probable class as a :class:`Terrain` label: (..., D) -> (...,) int8."""
        return np.argmax(self.log_joint(obs), axis=-1).astype(np.int8)

    def novelty(self, obs: np.ndarray) -> np.ndarray:
        """Chi2 surprise of the nearest safe class, ``-log P(chi2_D >= min_c m_c)``: (...,).

        0 for an observation at a class mean; a safe cell scores about 0.7 on average; lava
        scores far higher (see the module docstring).
        """
        from scipy.stats import chi2  # noqa: PLC0415 - scipy.stats costs every node process 0.3 s at start

        nearest = np.min(self.mahalanobis_sq(obs), axis=-1)
        return -chi2.logsf(nearest, df=self.dim)


def fit_classifier(
    model: ObservationModel, seed: int | np.random.Generator, samples_per_class: int = 1000
) -> TerrainClassifier:
    """Fit the QDA safe-terrain classifier on fresh samples of dirt, grass and target only.

    Args:
        model: the observation model the designer's training data come from.
        seed: int seed or numpy Generator.
        samples_per_class: samples of each safe terrain (> D, so covariances are full rank).

    Returns:
        The fitted :class:`TerrainClassifier`.
    """
    if not isinstance(samples_per_class, (int, np.integer)) or samples_per_class <= model.dim:
        raise ValueError(
            f"samples_per_class must be an integer > D = {model.dim}, got {samples_per_class!r}"
        )
    rng = as_generator(seed)
    labels = np.repeat(np.array(SAFE_TERRAINS, dtype=np.int64), samples_per_class)
    samples = sample_observations(model, labels, rng).reshape(
        len(SAFE_TERRAINS), samples_per_class, model.dim
    )
    means = samples.mean(axis=1)
    centred = samples - means[:, None, :]
    covariances = np.einsum("cni,cnj->cij", centred, centred) / (samples_per_class - 1)
    ridge = _RIDGE * np.trace(covariances, axis1=1, axis2=2) / model.dim
    covariances += ridge[:, None, None] * np.eye(model.dim)
    log_priors = np.full(len(SAFE_TERRAINS), -np.log(len(SAFE_TERRAINS)))
    return TerrainClassifier(means=means, covariances=covariances, log_priors=log_priors)
