"""The suite's process policy, set as the command line sets it at its entry."""


def pytest_configure(config):
    """The process's policy (BLAS threads, the allocator), as the command line sets
    it at its entry (acousim.process)."""
    from acousim.process import configure

    configure()
