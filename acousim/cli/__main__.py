"""``python -m acousim.cli``: the same as the ``acousim`` command."""

from . import run

run()
