"""
The random bit-rock law and the statistics of Monte Carlo studies (paper Sect. 3-4).

- ``germ``: the random germ [G_b] (Appendix B) and per-realization random streams.
- ``statistics``: envelopes, Fourier moduli, coefficients of variation, convergence.

Pure numpy; every random draw takes an explicit ``numpy.random.Generator``.
"""
