import os
import sys

from app.cli import main

code = main()
if "ompl" in sys.modules:
    # OMPL's nanobind bindings report "leaked" objects at interpreter shutdown (harmless); a user should not read
    # that after a clean run, so the process ends here.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
sys.exit(code)
