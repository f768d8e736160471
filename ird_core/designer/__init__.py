"""The designer in the loop (docs/spec.md section 7): which question to ask, and a simulated
designer who answers it.

Modules: ``queries`` (candidate paths, information gain, proposal, the simulated designer),
``proxy_queries`` (Active IRD's proxy-choice query).
"""
