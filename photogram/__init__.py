"""photogram: close-range photogrammetry and multi-camera sports motion capture."""

import os as _os
import sys as _sys

__version__ = "0.1.0"

# The dense systems of a bundle adjustment are small (hundreds of unknowns):
# BLAS threads cost more in wake-ups than they save, and on a busy machine a
# multi-threaded 135x135 Cholesky was seen to take 0.16 s instead of 0.2 ms.
# Use one BLAS thread unless the user chose otherwise before importing numpy.
if "numpy" not in _sys.modules:
    _os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
