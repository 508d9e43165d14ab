"""
Ensemble data assimilation: the twin follows the rig.

A pure numerical core (never imports rclpy): the ensemble Kalman analysis
(:mod:`.filter`), its settings (:mod:`.settings`), what a rig measures and how
(:mod:`.measurements`), the analysed state of a batch of members (:mod:`.state`), the rig
emulator (:mod:`.rig_emulator`) and the offline run of the filter over a recorded log
(:mod:`.offline`). docs/ASSIMILATION.md describes the choices.
"""
