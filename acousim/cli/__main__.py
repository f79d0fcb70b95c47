"""``python -m acousim.cli``: the same as the ``acousim`` command."""

from acousim.cli import run

run()
