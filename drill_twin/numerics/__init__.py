"""The numba plumbing the compiled kernels share: compilation, padded rows, records, recycling."""
