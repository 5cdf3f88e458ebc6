"""Synthetic networks with known truth (tests, example projects, design);
``ski``: the simulated giant-slalom runs for motion capture and their
rendered images. Above :mod:`photogram.mocap` in the layers (it may import
it, never the reverse)."""
