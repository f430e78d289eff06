"""``python -m moreau``: the same as the ``moreau`` command."""

import sys

from moreau.cli import main

sys.exit(main())
