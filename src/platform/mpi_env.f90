!> The MPI environment: world communicator, rank, size, and reductions that cost nothing on one
!> rank (a single-rank run makes no MPI call after initialisation).
module terrace_mpi_env
    use terrace_kinds, only: dp, i8
    use mpi_f08, only: MPI_Comm, MPI_Op, MPI_Datatype, MPI_COMM_WORLD, MPI_Init, MPI_Comm_rank, MPI_Comm_size, &
                       MPI_Allreduce, MPI_IN_PLACE, MPI_DOUBLE_PRECISION, MPI_INTEGER8, &
                       MPI_LOGICAL, MPI_SUM, MPI_MAX, MPI_MIN, MPI_LOR, MPI_Bcast, &
                       MPI_CHARACTER, MPI_INTEGER, MPI_Finalize, MPI_Allgather
    implicit none
    private

    type, public :: mpi_env_t
        type(MPI_Comm) :: comm
        integer :: rank = 0
        integer :: nprocs = 1
    end type mpi_env_t

    type(mpi_env_t), public, protected :: world

    public :: start_mpi, end_mpi, use_communicator, sum_all, max_all, min_all, any_all, sum_all_i8, bcast_text, &
              gather_counts

    interface
        !> Offers Open MPI's light singleton start-up when no launcher started the process
        !> (mpi_start.c).
        subroutine prepare_singleton() bind(C, name='terrace_prepare_singleton')
        end subroutine prepare_singleton
    end interface

contains

    subroutine start_mpi()
        call prepare_singleton()
        call MPI_Init()
        call use_communicator(MPI_COMM_WORLD)
    end subroutine start_mpi

    !> Run on an existing communicator (MPI already initialised: unit tests, embedding).
    subroutine use_communicator(comm)
        type(MPI_Comm), intent(in) :: comm
        world%comm = comm
        call MPI_Comm_rank(comm, world%rank)
        call MPI_Comm_size(comm, world%nprocs)
    end subroutine use_communicator

    subroutine end_mpi()
        call MPI_Finalize()
    end subroutine end_mpi

    !> x(1:n) becomes op over all ranks of x(1:n), in place (nothing is called on one rank): the one
    !> reduction the typed ones below share.
    subroutine reduce_in_place(x, n, datatype, op)
        type(*), intent(inout) :: x(..)
        integer, intent(in) :: n
        type(MPI_Datatype), intent(in) :: datatype
        type(MPI_Op), intent(in) :: op
        if (world%nprocs > 1) call MPI_Allreduce(MPI_IN_PLACE, x, n, datatype, op, world%comm)
    end subroutine reduce_in_place

    !> The reductions below take a scalar or a contiguous array (assumed rank: size(x) is 1 for a
    !> scalar).
    subroutine sum_all(x)
        real(dp), intent(inout) :: x(..)
        call reduce_in_place(x, size(x), MPI_DOUBLE_PRECISION, MPI_SUM)
    end subroutine sum_all

    subroutine sum_all_i8(n)
        integer(i8), intent(inout) :: n
        call reduce_in_place(n, 1, MPI_INTEGER8, MPI_SUM)
    end subroutine sum_all_i8

    subroutine max_all(x)
        real(dp), intent(inout) :: x
        call reduce_in_place(x, 1, MPI_DOUBLE_PRECISION, MPI_MAX)
    end subroutine max_all

    subroutine min_all(x)
        real(dp), intent(inout) :: x(..)
        call reduce_in_place(x, size(x), MPI_DOUBLE_PRECISION, MPI_MIN)
    end subroutine min_all

    subroutine any_all(flag)
        logical, intent(inout) :: flag
        call reduce_in_place(flag, 1, MPI_LOGICAL, MPI_LOR)
    end subroutine any_all

    !> Every rank's count n, in rank order (counts), and where each rank's part starts in their
    !> concatenation (displs: the sum of the counts before it), as MPI_Allgatherv wants them.
    !> counts and displs hold one entry per rank. Collective.
    subroutine gather_counts(n, counts, displs)
        integer, intent(in) :: n
        integer, intent(out) :: counts(:), displs(:)
        integer :: k
        call MPI_Allgather(n, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, world%comm)
        displs(1) = 0
        do k = 2, world%nprocs
            displs(k) = displs(k - 1) + counts(k - 1)
        end do
    end subroutine gather_counts

    !> Broadcast an allocatable string from rank 0.
    subroutine bcast_text(text)
        character(len=:), allocatable, intent(inout) :: text
        integer :: n
        if (world%nprocs == 1) return
        n = 0
        if (world%rank == 0) n = len(text)
        call MPI_Bcast(n, 1, MPI_INTEGER, 0, world%comm)
        if (world%rank /= 0) then
            if (allocated(text)) deallocate (text)
            allocate (character(len=n) :: text)
        end if
        if (n > 0) call MPI_Bcast(text, n, MPI_CHARACTER, 0, world%comm)
    end subroutine bcast_text

end module terrace_mpi_env
