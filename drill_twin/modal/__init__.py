"""Normal modes of the prestressed string and the reduced basis (paper Sect. 2.10)."""
