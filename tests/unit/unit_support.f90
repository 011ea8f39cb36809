!> Helpers shared by the Terrace unit tests (compiled into each test executable that needs them):
!> a deterministic random stream (identical on every rank), the rebuild sequence of
!> engine_rebuild, minimum-image distances and neighbour-pair bookkeeping by global atom id.
!>
!> Ghost atoms carry no id; the tests store the global id in v(1, :) of every owned atom before
!> the halo is built, and borders() copies velocities into the ghosts, so nint(v(1, j)) is the id
!> of any atom j, owned or ghost.
module unit_support
    use terrace_kinds, only: dp, i8
    use terrace_box, only: box_t
    use terrace_atoms, only: atoms_t
    use terrace_domain, only: domain_t
    use terrace_neighbor_list, only: neighbor_list_t
    use mpi_f08, only: MPI_Comm, MPI_Comm_free, MPI_Allreduce, MPI_IN_PLACE, MPI_INTEGER, &
                       MPI_DOUBLE_PRECISION, MPI_SUM
    implicit none
    private

    public :: rng_t, rebuild, min_image_rsq, count_list_pairs, expected_pairs, id_of, sum_over, free_comm

    !> In-place sums over a communicator (here, not in the .pf files: pFUnit's module exports the
    !> names of the `mpi` module, which clash with those of mpi_f08).
    interface sum_over
        module procedure sum_i0, sum_i1, sum_i2, sum_r0, sum_r2
    end interface sum_over

    !> Park-Miller minimal standard generator: the same sequence on every rank and compiler.
    type, public :: rng_t
        integer(i8) :: state = 20240601_i8
    contains
        procedure :: uniform => rng_uniform
    end type rng_t

contains

    !> Uniform deviate in (0, 1).
    real(dp) function rng_uniform(self) result(u)
        class(rng_t), intent(inout) :: self
        self%state = mod(16807_i8*self%state, 2147483647_i8)
        u = real(self%state, dp)/2147483647.0_dp
    end function rng_uniform

    !> The sequence of src/engine/engine.f90 (engine_rebuild) for the cell-list path.
    subroutine rebuild(dom, list, atoms)
        type(domain_t), intent(inout) :: dom
        type(neighbor_list_t), intent(inout) :: list
        type(atoms_t), intent(inout) :: atoms
        real(dp) :: lo(3), hi(3)
        integer :: d, n
        call dom%migrate(atoms)
        n = atoms%nlocal
        lo = dom%sublo; hi = dom%subhi
        do d = 1, dom%box%dimension
            if (n > 0) then
                lo(d) = min(lo(d), minval(atoms%x(d, 1:n)))
                hi(d) = max(hi(d), maxval(atoms%x(d, 1:n)))
            end if
        end do
        lo = lo - dom%cutghost; hi = hi + dom%cutghost
        if (.not. dom%ghosts_below) lo(3) = lo(3) + dom%cutghost
        call list%setup_bins(lo, hi, n)
        call list%sort_owned(atoms)
        call dom%borders(atoms)
        list%half_images = dom%halved
        call list%build(atoms)
    end subroutine rebuild

    !> Global id of atom j (owned or ghost), from the id stored in v(1, :).
    pure integer function id_of(atoms, j)
        type(atoms_t), intent(in) :: atoms
        integer, intent(in) :: j
        id_of = nint(atoms%v(1, j))
    end function id_of

    !> Squared minimum-image distance (periodic dimensions of the box only).
    pure real(dp) function min_image_rsq(box, a, b) result(rsq)
        type(box_t), intent(in) :: box
        real(dp), intent(in) :: a(3), b(3)
        real(dp) :: dx
        integer :: d
        rsq = 0
        do d = 1, box%dimension
            dx = a(d) - b(d)
            if (box%periodic(d)) dx = dx - box%length(d)*anint(dx/box%length(d))
            rsq = rsq + dx*dx
        end do
        if (box%dimension == 2) rsq = rsq + (a(3) - b(3))**2
    end function min_image_rsq

    !> counts(a, b), a <= b: how many times the half list of this rank holds the pair of global ids
    !> (a, b), as (owned, owned) or (owned, ghost). Not reduced over ranks.
    subroutine count_list_pairs(atoms, list, natoms, counts)
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        integer, intent(in) :: natoms
        integer, intent(out) :: counts(natoms, natoms)
        integer :: i, k, a, b
        counts = 0
        do i = 1, atoms%nlocal
            do k = list%first(i), list%first(i + 1) - 1
                a = id_of(atoms, i); b = id_of(atoms, list%neigh(k))
                counts(min(a, b), max(a, b)) = counts(min(a, b), max(a, b)) + 1
            end do
        end do
    end subroutine count_list_pairs

    !> expected(a, b) = 1 for a < b within cut (minimum image), else 0. O(N^2) brute force.
    subroutine expected_pairs(box, x, cut, expected)
        type(box_t), intent(in) :: box
        real(dp), intent(in) :: x(:, :), cut
        integer, intent(out) :: expected(:, :)
        integer :: a, b
        expected = 0
        do b = 1, size(x, 2)
            do a = 1, b - 1
                if (min_image_rsq(box, x(:, a), x(:, b)) < cut*cut) expected(a, b) = 1
            end do
        end do
    end subroutine expected_pairs

    subroutine sum_i0(comm, a)
        type(MPI_Comm), intent(in) :: comm
        integer, intent(inout) :: a
        call MPI_Allreduce(MPI_IN_PLACE, a, 1, MPI_INTEGER, MPI_SUM, comm)
    end subroutine sum_i0

    subroutine sum_i1(comm, a)
        type(MPI_Comm), intent(in) :: comm
        integer, intent(inout) :: a(:)
        call MPI_Allreduce(MPI_IN_PLACE, a, size(a), MPI_INTEGER, MPI_SUM, comm)
    end subroutine sum_i1

    subroutine sum_i2(comm, a)
        type(MPI_Comm), intent(in) :: comm
        integer, intent(inout) :: a(:, :)
        call MPI_Allreduce(MPI_IN_PLACE, a, size(a), MPI_INTEGER, MPI_SUM, comm)
    end subroutine sum_i2

    subroutine sum_r0(comm, a)
        type(MPI_Comm), intent(in) :: comm
        real(dp), intent(inout) :: a
        call MPI_Allreduce(MPI_IN_PLACE, a, 1, MPI_DOUBLE_PRECISION, MPI_SUM, comm)
    end subroutine sum_r0

    subroutine sum_r2(comm, a)
        type(MPI_Comm), intent(in) :: comm
        real(dp), intent(inout) :: a(:, :)
        call MPI_Allreduce(MPI_IN_PLACE, a, size(a), MPI_DOUBLE_PRECISION, MPI_SUM, comm)
    end subroutine sum_r2

    !> Free a communicator made by a test (the domain's Cartesian one).
    subroutine free_comm(comm)
        type(MPI_Comm), intent(inout) :: comm
        call MPI_Comm_free(comm)
    end subroutine free_comm

end module unit_support
