"""The campaign engine: campaign files, the task grid, the MPI master/worker
scheduler and the resumable HDF5 store."""
