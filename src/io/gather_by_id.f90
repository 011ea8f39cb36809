!> Gather per-atom values of every rank on rank 0, sorted by global atom id: for the small
!> diagnostic text outputs (forces file, final atoms file). Production output (H5MD) never gathers.
module terrace_gather_by_id
    use terrace_kinds, only: dp, i8
    use terrace_heap_sort, only: sort_by_id
    use terrace_mpi_env, only: world
    use terrace_atoms, only: atoms_t
    use mpi_f08, only: MPI_Gather, MPI_Gatherv, MPI_INTEGER, MPI_INTEGER8, MPI_DOUBLE_PRECISION
    implicit none
    private

    public :: gather_by_id, gather_atoms_by_id

contains

    !> The type, position and (with_velocity) velocity of every owned atom, on rank 0 in id order:
    !> all_values(1, :) the type, (2:4, :) x, (5:7, :) v. Collective.
    subroutine gather_atoms_by_id(atoms, with_velocity, all_ids, all_values)
        type(atoms_t), intent(in) :: atoms
        logical, intent(in) :: with_velocity
        integer(i8), allocatable, intent(out) :: all_ids(:)
        real(dp), allocatable, intent(out) :: all_values(:, :)
        real(dp), allocatable :: mine(:, :)
        integer :: n, i
        n = atoms%nlocal
        allocate (mine(merge(7, 4, with_velocity), n))
        do i = 1, n
            mine(1, i) = real(atoms%type(i), dp)
            mine(2:4, i) = atoms%x(:, i)
            if (with_velocity) mine(5:7, i) = atoms%v(:, i)
        end do
        call gather_by_id(n, atoms%id(1:n), mine, all_ids, all_values)
    end subroutine gather_atoms_by_id

    !> values(nc, nlocal) of this rank's atoms ids(nlocal); on rank 0, all_ids(total) ascending and
    !> all_values(nc, total) in that order (empty on the other ranks). Collective.
    subroutine gather_by_id(nlocal, ids, values, all_ids, all_values)
        integer, intent(in) :: nlocal
        integer(i8), intent(in) :: ids(:)
        real(dp), intent(in) :: values(:, :)
        integer(i8), allocatable, intent(out) :: all_ids(:)
        real(dp), allocatable, intent(out) :: all_values(:, :)
        integer, allocatable :: counts(:), displs(:), order(:)
        integer(i8), allocatable :: gids(:)
        real(dp), allocatable :: gvals(:, :)
        integer :: nc, total, r, i
        nc = size(values, 1)
        allocate (counts(world%nprocs), displs(world%nprocs))
        call MPI_Gather(nlocal, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, 0, world%comm)
        total = 0
        if (world%rank == 0) then
            do r = 1, world%nprocs
                displs(r) = total; total = total + counts(r)
            end do
        end if
        allocate (gids(max(total, 1)), gvals(nc, max(total, 1)))
        call MPI_Gatherv(ids, nlocal, MPI_INTEGER8, gids, counts, displs, MPI_INTEGER8, 0, world%comm)
        call MPI_Gatherv(values, nc*nlocal, MPI_DOUBLE_PRECISION, gvals, nc*counts, nc*displs, MPI_DOUBLE_PRECISION, &
                         0, world%comm)
        allocate (order(total))
        order = [(i, i=1, total)]
        call sort_by_id(gids(1:total), order)
        all_ids = gids(order)
        all_values = gvals(:, order)
    end subroutine gather_by_id

end module terrace_gather_by_id
