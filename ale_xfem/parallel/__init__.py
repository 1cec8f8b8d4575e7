"""Runs on several MPI ranks (``mpiexec -n N ale-xfem run SCENE``): each rank steps its own
cells and the ghost layer around them, exchanging nodal forces through DOLFINx's index
maps (:mod:`ale_xfem.parallel.distribution`)."""
