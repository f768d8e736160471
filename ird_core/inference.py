"""The IRD posterior over the true reward weights (IRD_SPEC.md section 3) and its sampler.

Observation model (Hadfield-Menell et al. 2017, section 4): the designer picks the proxy ``w~``
with ``P(w~ | w*, M~) ∝ exp(beta * w* . phi~(w~))``, where ``phi~(w~)`` are the proxy's expected
feature counts in the training MDP ``M~`` under the MaxEnt agent. With a Gaussian prior
``N(0, sigma^2 I)`` the unnormalised log posterior of a candidate ``w`` is

- ``maxent_z``: ``beta * (w . phi~(w~) - log Z(w)) - |w|^2 / (2 sigma^2)``, i.e. MaxEnt IRL with
  ``beta`` pretend demonstrations whose feature counts are ``phi~(w~)``. Exact gradient
  ``beta * (phi~(w~) - phi~(w)) - w / sigma^2``; the log posterior is strictly concave.
- ``sample_z``: ``beta * w . phi~(w~) - logsumexp([beta w . phi~(w)] + [beta w . phi_i]_i)
  - |w|^2 / (2 sigma^2)``, with ``phi_i = phi~(w_i)`` for ``N`` proxies ``w_i`` drawn from the
  proxy prior ``N(0, sigma^2 I)`` once per training MDP, and the candidate's own ``phi~(w)``
  included as the paper recommends.

Sample-Z gradient. ``d/dw [w . phi~(w)] = phi~(w) + H(w) w`` with ``H(w) = Cov_w[phi]`` (the
Hessian of ``log Z``). ``H(w) w`` is the derivative of ``phi~(t w)`` in ``t`` at ``t = 1``; it is
computed by a forward difference along the ray, ``(phi~((1 + eps) w) - phi~(w)) / eps``
(``eps = 1e-6``, agrees with central differences of the log posterior to ~1e-6 relative), so
the value and the gradient come from ONE batched MDP call on ``2K`` weights. HMC stays exact
with this deterministic field; dropping the ``H(w) w`` term (half the cost) is also exact but
shrank the stable HMC step ten-fold on latent_raw, so the term is kept.

Posterior geometry (measured on latent_raw, d = 50, beta = 1). Both posteriors are a Gaussian
prior times a likelihood that is nearly piecewise linear: at typical posterior weights the
MaxEnt trajectory distribution is close to deterministic, so ``log Z`` is close to a max over
trajectories and the log posterior has sharp creases (curvature up to ~100x that at the mode,
in preconditioned units) where the preferred trajectory changes. Sample-Z is stiffer still: its
``logsumexp`` over the proxies' feature counts (norms ~100-250) is a near-hard max, and its
posterior is up to ~9x wider (in sd) than the Laplace approximation at its mode. The creases cap
the stable step size (~0.05 preconditioned units for MaxEnt-Z, ~0.02 for Sample-Z), so MALA and
RWM mix far too slowly in 50-d; HMC's ballistic trajectories do not.

Sampler (``sample_posterior``), defaults chosen on the 15x15, T = 30, d = 50 ``latent_raw``
benchmark (``scripts/bench_inference.py``):

1. A Laplace approximation: the MAP by damped Newton from ``w = 0``, each iteration one batched
   call for the gradient at ``w`` and at ``w + delta e_j`` (forward-difference Hessian, ``d + 1``
   weights) and one batched line search. The inverse negative Hessian at the MAP (eigenvalues
   floored) is the initial preconditioner: posterior standard deviations span ~0.02 to ~1 across
   directions, and a dense 50-d metric cannot be learnt from scratch in a short warm-up.
   At the experiments' beta = 50 the Sample-Z log density has creases ~1/beta wide and Newton
   can stall far from the mode (latent_raw, 100 proxies: log density -2.1 near ``w = 0`` against
   +33.4 at the mode). A stalled Newton (no ascent while its decrement is above 1e-3) is followed
   by L-BFGS with exact gradients, and the covariance's axes are narrowed to the measured extent
   of the log density along them (``ird_core.laplace``): the Hessian at a crease overstated it up
   to 1000x, which held HMC's step at ~5e-4. Smooth posteriors (MaxEnt-Z) never take this path.
2. ``num_chains`` (16) chains start at ``mode + 2 L z`` (``L L^T`` the Laplace covariance), i.e.
   overdispersed relative to the Laplace approximation, in the spirit of Gelman & Rubin (1992).
   Starting from the prior ``N(0, sigma^2 I)`` (``init="prior"``, available) is more
   conservative, but in 50-d the prior mass is hundreds of nats away from the posterior and the
   chains need far longer warm-ups to get there. R-hat is computed on post-warm-up draws only,
   rank-normalised and folded, so chains that disagree in location or in scale are both caught.
3. HMC (``kernel="hmc"``; ``"mala"``, ``"rwm"`` and the gradient-free ``"elliptical"`` slice
   sampler, ``"independence"`` Metropolis with a Student-t proposal and
   ``"independence_elliptical"`` (one of each per iteration), all three around the adapted
   Gaussian, are available) with a dense metric: a shared
   step size adapted by dual averaging towards acceptance 0.8 (chain-averaged acceptance
   probability), trajectories of 1.5 preconditioned units (at most ``DEFAULT_MAX_LEAPFROG``
   leapfrog steps, per-chain step jitter +-10%), and Stan-style windows that re-estimate the
   metric from the draws of all chains pooled, shrunk towards the current metric with
   Ledoit-Wolf weights (see ``ird_core.mcmc``). Warm-up trajectories are capped at 8 leapfrog
   steps until the final buffer, which tunes the step at the full trajectory length. Everything
   is frozen after warm-up, so the retained draws come from one fixed, valid kernel.
   Per-method defaults: MaxEnt-Z 100 warm-up iterations, >= 120 iterations per chain after
   warm-up, <= 32 leapfrog steps; Sample-Z 150, >= 100 and <= 64 (``thin=None`` picks the
   thinning that gives each chain at least that many iterations).
4. Draws are thinned, pooled draw-major (first retained draw of every chain, then the second,
   ...) and cut to exactly ``num_samples``; diagnostics use every retained draw: rank-normalised
   split R-hat (max of bulk and folded, Vehtari et al. 2021) and bulk ESS.

Default number of proxy samples for Sample-Z: ``DEFAULT_NUM_PROXY_SAMPLES = 1000``. Their
feature expectations cost one batched pass once (about 0.4 s on 15x15, T = 30), and each MCMC
step only adds a ``(K, d) x (d, N)`` product and a softmax, negligible next to the MDP pass, so
``N`` is cheap. It matters: the Sample-Z normaliser is a log-mean-exp of near-max terms and
converges slowly. On latent_raw (seed 0, beta 1) the rms error of log-posterior differences
between 256 posterior-typical weights, against N = 6400 proxies, is 6.0 / 4.1 / 3.4 / 2.5 / 1.9 /
0.9 nats for N = 25 / 100 / 200 / 400 / 800 / 1600, for differences whose spread is 8.0 nats
(``scripts/bench_inference.py --proxy-study``). 1000 keeps the approximation error near 1.5
nats at well under a second of set-up.

``beta = 0`` is allowed (the posterior is then the prior); negative beta is an error.

Evidence from the designer (IRD_SPEC 7): ``ProxyObservation`` s (several training worlds) and
``ChoiceObservation`` s (answered queries) enter one joint posterior, ``joint_log_posterior`` and
``sample_joint_posterior``; the single-proxy functions above are the joint ones with one
``ProxyObservation``. ``sample_joint_posterior(..., initial=previous_posterior)`` warm starts a
re-sample after one more answer (``ird_core.sampler``).

This module is the public namespace; the code lives in ``ird_core.likelihoods`` (per-term log
likelihoods and gradients, proxy feature counts), ``ird_core.evidence`` (observations, the joint
posterior model), ``ird_core.sampler`` (Laplace start, HMC, ``Posterior``) and
``ird_core.checks`` (argument validation).
"""

from __future__ import annotations

# The public namespace: every name of the three modules (their ``__all__``) and the request
# check, so a name is listed once, where it is defined.
from ird_core import evidence, likelihoods, sampler
from ird_core.checks import check_posterior_arguments
from ird_core.evidence import *  # noqa: F401,F403
from ird_core.likelihoods import *  # noqa: F401,F403
from ird_core.sampler import *  # noqa: F401,F403

__all__ = [*likelihoods.__all__, *evidence.__all__, *sampler.__all__, "check_posterior_arguments"]

