"""The suite's process policy, set as the command line sets it at its entry."""


def pytest_configure(config):
    """The process's policy (BLAS threads, the allocator), as the command line sets
    it at its entry (acousim.process)."""
    from acousim.process import configure

    configure()


def pytest_collection_modifyitems(session, config, items):
    """The order of the run (each module's tests kept together and in order, so a
    module's fixtures are made once; the same order in every worker):

    1. the modules marked ``forks`` (``Simulator.run`` and the forked worker: a
       process where a parallel kernel has run may no longer fork, and those tests
       would check less), before anything else in their worker;
    2. the modules holding a test marked ``slow``: with ``make test``'s ``-n 2
       --dist worksteal`` the first worker starts on the longest tests (a wheel
       installed and its kernels compiled, the README's commands) while the other
       takes the short ones and steals what is left at the end, instead of one
       worker finishing a long test alone at the end (they are collected last);
    3. the rest."""
    forks = {item.module.__name__ for item in items if item.get_closest_marker("forks")}
    slow = {item.module.__name__ for item in items if item.get_closest_marker("slow")}
    order = {id(item): k for k, item in enumerate(items)}

    def rank(item) -> tuple[int, int]:
        name = item.module.__name__
        return (0 if name in forks else 1 if name in slow else 2, order[id(item)])

    items.sort(key=rank)
