"""
drill_twin: a digital twin of a drill string (Ritto, Soize & Sampaio 2009).

The folders are the layers, lowest first; each imports only those below it (the contract is
setup.cfg's ``[importlinter]``, checked by ``lint-imports`` in the tests):

- ``config``, ``interface``: YAML -> validated frozen dataclasses; the ROS interface's names.
- ``numerics``: the numba plumbing the compiled kernels share.
- ``fem``: the finite-element model of the string (Sect. 2.1-2.9).
- ``modal``: normal modes and the reduced basis (Sect. 2.10).
- ``model``: the equations, without state: forces, finite strain, contact, bit-rock law.
- ``integrator``: batch state, implicit Newmark, the Simulator and its guard.
- ``rig``: top drive, controllers, drawworks, what the surface sensors read.
- ``analysis``: linear stability, steady drilling, power balances, KPIs, pre-flight checks.
- ``simulation``: offline runs, histories, summaries, the stick-slip map.
- ``uncertainty``: the random bit-rock law's germ and Monte Carlo studies (Sect. 3-4).
- ``assimilation``: the ensemble Kalman filter that follows a rig.
- ``twin``: the twin's engine (mean model, online ensemble, commands, events), ROS-free.
- ``recording``: rosbag2 bags of MCAP files, read and written.
- ``viz``: figures, the rerun layout and viewer, the live view, the console status.
- ``ros``: the rclpy node, a thin boundary around ``twin``.
- ``cli``: the ``drill-twin`` command.

Everything below ``ros`` is free of ROS (and of plotting) and can be used offline.
"""

__version__ = '0.1.0'
