"""ird_core: Inverse Reward Design (Hadfield-Menell et al., NIPS 2017) in pure numpy/scipy.

No ROS import anywhere in this package: researchers use it directly.

Sub-packages, each ``__init__`` its public API; imports point one way (vocabulary and checks,
then mdp, worlds, posterior and mcmc, planning, hypothesis, designer, experiments):

    vocabulary   the names that select a behaviour (StrEnums) and ``parse``
    checks       argument validation and numeric ranges
    mdp          grid MDPs and exact MaxEnt trajectory inference (docs/spec.md sections 1-2)
    worlds       terrain, observations, Lavaland instances, world files, path evaluation (section 5)
    posterior    the IRD posterior: likelihoods, evidence, proxy observations, sampler (sections 3, 7)
    mcmc         batched MCMC kernels, warm-up adaptation, chains, diagnostics
    planning     literal and risk-averse planners, the exact trajectory solver (section 4)
    hypothesis   IRD's hypothesis space: linear, random Fourier features, the novel feature
    designer     information gain, query proposal, the simulated designer (section 7)
    experiments  the paper's experiments (Figure 4, appendix factorial) and the active one
    render       PNG pictures of maps and paths
"""

__version__ = "0.1.0"
