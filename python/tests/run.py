"""Run one pytest case for ctest: exit 77 (skipped) when numpy or pytest
is missing (scripts/setup-deps.sh installs python3-numpy, python3-pytest)."""
import sys

try:
    import numpy  # noqa: F401
    import pytest
except ImportError as e:
    print(f"skipped: {e} (Debian: apt-get install python3-numpy python3-pytest)")
    sys.exit(77)
sys.exit(pytest.main(["-q", "-p", "no:cacheprovider", *sys.argv[1:]]))
