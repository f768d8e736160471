"""The designer in the loop (docs/spec.md section 7): which question to ask, and a simulated
designer who answers it.

Modules: ``queries`` (information gain, proposal, the simulated designer), ``candidates`` (the
paths a question may offer), ``decision`` (EVOI, maximum regret, the oracle query),
``proxy_queries`` (Active IRD's proxy-choice query).
"""
