"""CTest entry for the Python package's tests: skips (exit 77, CTest's SKIP_RETURN_CODE)
with a message when numpy or h5py is missing, else runs every test_*.py here."""

import os
import sys
import unittest

try:
    import h5py  # noqa: F401
    import numpy  # noqa: F401
except ImportError as e:
    print(f"skipped: {e}; install Debian's python3-numpy python3-h5py (tools/setup.sh does)")
    sys.exit(77)

here = os.path.dirname(os.path.abspath(__file__))
suite = unittest.defaultTestLoader.discover(here)
result = unittest.TextTestRunner(verbosity=2).run(suite)
sys.exit(0 if result.wasSuccessful() else 1)
