"""ird_core: Inverse Reward Design (Hadfield-Menell et al., NIPS 2017) in pure numpy/scipy.

No ROS import anywhere in this package: researchers use it directly.

Modules:
    mdp               exact MaxEnt trajectory inference on deterministic grid MDPs
    enumeration       brute-force references over all trajectories (tiny grids, for tests)
    terrain           Lavaland terrain types and the seeded map sampler
    observations      the Gaussian observation model and the safe-terrain classifier
    lavaland          the paper's four conditions, pot_of_gold, proxies and the true reward
    world_file        worlds from YAML + PNG files, as Lavaland instances
    inference         the IRD posterior's public namespace (re-exports the four below)
    likelihoods       per-term log likelihoods and gradients; proxy feature counts
    evidence          proxy and choice observations; the joint posterior
    laplace           the sampler's start: the posterior mode and a covariance there
    sampler           the posterior sampler: HMC / slice / independence chains, warm start, run until converged
    checks            argument validation and numeric ranges
    mcmc_kernels      RWM, MALA, HMC, elliptical slice, independence MH as init/step pairs (blackjax-shaped)
    mcmc              warm-up schedule, sample_chains, continue_chains
    diagnostics       split / rank-normalised R-hat, ESS
    queries           information gain, query proposal, the simulated designer
    planning          literal and risk-averse planners, reward baselines, risk map
    trajectory_solver the exact trajectory-min solver (label search, MILP), time or work limited
    trajectory_bounds exact DP tables over the time-expanded graph (the trajectory solver's bounds)
    experiments       the paper's experiments (Figure 4, appendix factorial)
    active            the designer-in-the-loop experiment
    render            PNG pictures of maps and paths
"""

__version__ = "0.1.0"
