"""Run an example script for ctest: exit 77 (skipped) without numpy."""
import runpy
import sys

try:
    import numpy  # noqa: F401
except ImportError as e:
    print(f"skipped: {e} (Debian: apt-get install python3-numpy)")
    sys.exit(77)
script = sys.argv[1]
sys.argv = sys.argv[1:]
runpy.run_path(script, run_name="__main__")
