"""``python -m psdm_casadi``: the ``psdm`` command line (``psdm_casadi.cli.main``) where the entry point is not on the
PATH, as in a virtual environment that is not activated (``.venv/bin/python -m psdm_casadi identify ...``)."""

import sys

from psdm_casadi.cli import main

if __name__ == "__main__":
    sys.exit(main())
