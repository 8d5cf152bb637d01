"""``python -m tapm_opt`` runs the ``tapm`` command."""

import sys

from .cli import main

sys.exit(main())
