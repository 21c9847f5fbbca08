"""``python -m cloudmeta.cli``: the same as the ``cloudmeta`` command."""
import sys

from . import main

sys.exit(main())
