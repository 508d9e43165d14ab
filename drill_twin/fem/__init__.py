"""
The finite-element model of the string (paper Sect. 2.1-2.9).

``mesh`` and ``shape_functions`` describe the Timoshenko element; ``strain_energy`` its
finite-strain energy; ``element_matrices``, ``fluid`` and ``assembly`` the matrices;
``prestress`` the static state; ``model`` puts them together.
"""
