!> Replicated-data halo for small all-pairs scenes: every rank receives every other rank's atoms
!> (MPI_Allgatherv) as ghosts. Only used when the scene plan picks all pairs on several ranks.
module terrace_replicate
    use terrace_kinds, only: dp
    use terrace_atoms, only: atoms_t
    use terrace_mpi_env, only: world, gather_counts
    use mpi_f08, only: MPI_Allgatherv, MPI_DOUBLE_PRECISION
    implicit none
    private

    type, public :: replicate_t
        integer, allocatable :: counts(:), displs(:)
        real(dp), allocatable :: buf(:)
        integer :: total = 0
    contains
        procedure :: setup => replicate_setup
        procedure :: gather => replicate_gather
    end type replicate_t

contains

    !> Exchange the owned counts and the ghost types (after any change of ownership).
    subroutine replicate_setup(self, atoms)
        class(replicate_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        integer :: r, k, j, n
        if (.not. allocated(self%counts)) allocate (self%counts(world%nprocs), self%displs(world%nprocs))
        call gather_counts(atoms%nlocal, self%counts, self%displs)
        self%total = sum(self%counts)
        if (allocated(self%buf)) deallocate (self%buf)
        allocate (self%buf(3*max(self%total, 1)))
        atoms%nghost = 0
        call atoms%reserve(self%total)
        atoms%nghost = self%total - atoms%nlocal
        ! types
        call MPI_Allgatherv(real(atoms%type(1:atoms%nlocal), dp), atoms%nlocal, MPI_DOUBLE_PRECISION, self%buf, &
                            self%counts, self%displs, MPI_DOUBLE_PRECISION, world%comm)
        n = atoms%nlocal
        do r = 1, world%nprocs
            if (r - 1 == world%rank) cycle
            do k = 1, self%counts(r)
                j = self%displs(r) + k
                n = n + 1
                atoms%type(n) = nint(self%buf(j))
            end do
        end do
        call self%gather(atoms, atoms%x)
        call self%gather(atoms, atoms%v)
    end subroutine replicate_setup

    !> Copy every other rank's owned values of a per-atom 3-vector into this rank's ghosts.
    subroutine replicate_gather(self, atoms, a)
        class(replicate_t), intent(inout) :: self
        type(atoms_t), intent(in) :: atoms
        real(dp), intent(inout) :: a(:, :)
        integer :: r, n, j
        call MPI_Allgatherv(a(:, 1:atoms%nlocal), 3*atoms%nlocal, MPI_DOUBLE_PRECISION, self%buf, 3*self%counts, &
                            3*self%displs, MPI_DOUBLE_PRECISION, world%comm)
        n = atoms%nlocal
        do r = 1, world%nprocs
            if (r - 1 == world%rank) cycle
            j = 3*self%displs(r)
            a(:, n + 1:n + self%counts(r)) = reshape(self%buf(j + 1:j + 3*self%counts(r)), [3, self%counts(r)])
            n = n + self%counts(r)
        end do
    end subroutine replicate_gather

end module terrace_replicate
