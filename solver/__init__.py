"""Physics only: droplet geometry, the elastic shell model, its solvers and the
effective modulus. Imports nothing of `campaign` or `analysis`; no MPI, no files."""
