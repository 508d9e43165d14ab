"""
drill_twin: a digital twin of a vertical drill string.

The package is layered; the folders say how:

- ``config``: YAML files -> validated, frozen dataclasses.
- ``fem``: the finite-element model of the string (Ritto, Soize & Sampaio 2009, Sect. 2).
- ``modal``: normal modes and the reduced basis (Sect. 2.10).
- ``dynamics``: non-linear forces and the Newmark integrator on the reduced model.
- ``uncertainty``: the random bit-rock law and Monte Carlo studies (Sect. 3-4).
- ``recording``: MCAP logs and the rerun viewer.
- ``ros``: the rclpy node, a thin boundary around the core.
- ``cli``: the ``drill-twin`` command.

Everything except ``ros`` (and the parts of ``recording`` that need message classes)
is free of ROS and can be used offline.
"""

__version__ = '0.1.0'
