"""Analyses of the model: linear stability, steady drilling, power balances, KPIs, pre-flight."""
