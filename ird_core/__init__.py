"""ird_core: Inverse Reward Design (Hadfield-Menell et al., NIPS 2017) in pure numpy/scipy.

No ROS import anywhere in this package: researchers use it directly.

Modules:
    mdp          exact MaxEnt trajectory inference on deterministic grid MDPs
    enumeration  brute-force references over all trajectories (tiny grids, for tests)
    terrain      Lavaland terrain types and the seeded map sampler
    observations the Gaussian observation model and the safe-terrain classifier
    lavaland     the paper's four conditions, proxies and the true reward
    inference    the IRD posterior (MaxEnt-Z, Sample-Z) and its MCMC sampler
    planning     literal and risk-averse planners, reward baselines, risk map
    render       PNG pictures of maps and paths
"""

__version__ = "0.1.0"
