"""Stepping the reduced model: batch state, implicit Newmark, the Simulator and its guard."""
