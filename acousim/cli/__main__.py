"""``python -m acousim.cli``: the same as the ``acousim`` command."""

import sys

from . import main

sys.exit(main())
