"""The rig's machines: top drive and its controllers, drawworks, surface readings."""
