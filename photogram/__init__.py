"""photogram: close-range photogrammetry and multi-camera sports motion capture."""

__version__ = "0.1.0"
