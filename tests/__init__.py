"""The test suite, laid out like the code (tests/processing, tests/acousim, tests/hardware;
tests/system for the whole installed thing; tests/oracles for the independent references
several tests share)."""

from pathlib import Path

#: the checkout's root (scenes/, datasets/, README.md)
REPO = Path(__file__).resolve().parent.parent
