"""The suite's process policy, set as the command line sets it at its entry."""


def pytest_configure(config):
    """The process's policy (BLAS threads, the allocator), as the command line sets
    it at its entry (acousim.process)."""
    from acousim.process import configure

    configure()


def pytest_collection_modifyitems(session, config, items):
    """The modules holding a test marked ``slow`` first (each module's tests kept
    together and in order, so a module's fixtures are made once): with ``make
    test``'s ``-n 2 --dist worksteal`` the first worker starts on the longest tests
    (a wheel installed and its kernels compiled, the README's commands) while the
    other takes the short ones and steals what is left at the end, instead of one
    worker finishing a long test alone at the end (those modules are collected
    last).  The same order in every worker."""
    slow = {item.module.__name__ for item in items if item.get_closest_marker("slow")}
    order = {id(item): k for k, item in enumerate(items)}
    items.sort(key=lambda item: (item.module.__name__ not in slow, order[id(item)]))
