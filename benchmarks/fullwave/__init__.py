"""Our own full-wave reference for small rigid objects (issue 13), with bempp-cl.

Independent of the simulator (nothing here imports ``acousim``): meshes are built in
numpy (`geometry`), the exact rigid-sphere series is written out with scipy.special
(`series`), and the boundary-element solves use bempp-cl (`solve`, optional extra
``fullwave``). `compute` runs the cases and caches the levels in
``benchmarks/data/fullwave.csv``; `compare` (benchmark section ``fullwave``) reads that
file and sets our simulator's levels beside it.
"""
