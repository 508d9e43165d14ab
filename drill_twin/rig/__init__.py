"""The rig: commands turned into the simulator's inputs (``Rig``), its drives, surface readings."""
