"""MPI really runs across ranks, and on the parallel-HDF5 stack a collective
`mpio` file can be written by all ranks at once.

Run as `mpiexec -n 2 python -m pytest --with-mpi -m mpi tests` (Makefile
`test-mpi`, `test-mpi-parallel`).
"""

import numpy as np
import pytest

ROWS = 5      # rows written by each rank
COLS = 3


@pytest.mark.mpi(min_size=2)
def test_allreduce_sums_over_ranks():
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    n, rank = comm.Get_size(), comm.Get_rank()
    assert comm.allreduce(rank + 1, op=MPI.SUM) == n * (n + 1) // 2
    # buffer form: each rank contributes a distinct vector
    mine = np.arange(4, dtype=float) * (rank + 1)
    total = np.empty_like(mine)
    comm.Allreduce(mine, total, op=MPI.SUM)
    np.testing.assert_array_equal(total, np.arange(4) * n * (n + 1) / 2)
    assert comm.allgather(rank) == list(range(n))


def _row_values(rank):
    """What rank `rank` writes: row i, column j = 100 rank + 10 i + j."""
    i, j = np.mgrid[0:ROWS, 0:COLS]
    return 100.0 * rank + 10.0 * i + j


@pytest.mark.mpi(min_size=2)
def test_collective_mpio_write(tmp_path_factory):
    import h5py
    from mpi4py import MPI
    if not h5py.get_config().mpi:
        pytest.skip("h5py is built without MPI on this stack (the default stack writes "
                    "from rank 0); parallel HDF5: make setup-parallel")
    comm = MPI.COMM_WORLD
    n, rank = comm.Get_size(), comm.Get_rank()
    path = comm.bcast(str(tmp_path_factory.mktemp("mpio") / "rows.h5") if rank == 0 else None)

    with h5py.File(path, "w", driver="mpio", comm=comm) as f:
        assert f.driver == "mpio"
        dset = f.create_dataset("rows", (n * ROWS, COLS), dtype="f8")
        with dset.collective:
            dset[rank * ROWS:(rank + 1) * ROWS] = _row_values(rank)
        f.attrs["ranks"] = n
    comm.Barrier()

    # read back serially on rank 0, and collectively with each rank reading
    # another's block; assert only after the last collective call, so that a
    # failure on one rank cannot leave the other waiting in a collective open
    got = None
    if rank == 0:
        with h5py.File(path, "r") as f:
            got = (int(f.attrs["ranks"]), f["rows"][...])
    got = comm.bcast(got)
    other = (rank + 1) % n
    with h5py.File(path, "r", driver="mpio", comm=comm) as f:
        block = f["rows"][other * ROWS:(other + 1) * ROWS]

    assert got[0] == n
    np.testing.assert_array_equal(got[1], np.concatenate([_row_values(r) for r in range(n)]))
    np.testing.assert_array_equal(block, _row_values(other))
