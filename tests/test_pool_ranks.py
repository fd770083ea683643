"""`common.pool`: under an MPI launcher rank 0's pools map over the other ranks (`ranks`),
every pool it opens inside, one round after another; rank 0 forks no child there
(`common.beside.forking`); without a launcher the pools are as before.

The MPI test runs as `mpiexec -n 2 python -m pytest --with-mpi -m mpi tests` (Makefile
`test-mpi`, `test-mpi-parallel`); the others in the serial suite."""

import pytest

from common.beside import forking
from common.pool import Serial, inside_ranks, launched_ranks, pool, ranks, usable_cores


def _square_on(x):
    """x², and the rank that computed it."""
    from mpi4py import MPI
    return x * x, MPI.COMM_WORLD.Get_rank()


@pytest.mark.mpi(min_size=2)
def test_rank_0s_pools_are_the_other_ranks():
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    with ranks() as main:
        assert main == (comm.Get_rank() == 0)
        if main:
            assert inside_ranks() and not forking()
            for jobs in (1, 4):                                   # two rounds; `jobs` is not used
                with pool(jobs) as workers:
                    done = list(workers.map(_square_on, range(9)))
                assert [value for value, _ in done] == [x * x for x in range(9)]
                assert {rank for _, rank in done} <= set(range(1, comm.Get_size()))
    assert not inside_ranks()
    assert comm.allgather(launched_ranks()) == [comm.Get_size()] * comm.Get_size()


def test_without_a_launcher_the_pools_are_this_processes(monkeypatch):
    for name in ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE"):
        monkeypatch.delenv(name, raising=False)
    assert launched_ranks() == 1
    with ranks() as main:
        assert main and not inside_ranks()
        assert isinstance(pool(1), Serial)
        assert forking() == (usable_cores() >= 2)
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "4")
    assert launched_ranks() == 4
    monkeypatch.setenv("PMI_SIZE", "3")
    assert launched_ranks() == 3
