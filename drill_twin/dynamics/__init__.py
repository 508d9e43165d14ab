"""
The non-linear mean model in time (paper Sect. 2.2-2.9 and 4).

``reduced_system`` precomputes the reduced matrices and interpolation operators; the forces of
Eq. 31 live in ``finite_strain``, ``kinetic_coupling``, ``contact`` and ``bit_rock`` and are
gathered by ``forces``; ``newmark`` integrates the reduced model for a batch of members.
"""
