!> A whole scene as read from a file on rank 0 (LAMMPS data file or atoms file), before the atoms
!> are handed to the ranks that own them.
module terrace_atom_table
    use terrace_kinds, only: dp, i8
    implicit none
    private

    type, public :: atom_table_t
        integer :: n = 0
        integer :: ntypes = 0
        real(dp) :: lo(3) = 0, hi(3) = 0
        logical :: has_box = .false.
        logical :: has_velocities = .false.
        logical :: has_masses = .false.
        real(dp), allocatable :: x(:, :), v(:, :), mass(:)
        integer, allocatable :: type(:), image(:, :)
        integer(i8), allocatable :: id(:)
        !> LAMMPS data files as write_data makes them: the 'Pair Coeffs' / 'PairIJ Coeffs' sections
        !> (epsilon, sigma of each pair; coeff_given(i, j) where the file gave it), checked
        !> against &potential by terrace_data_coeffs; coeff_style is the style named after '#'
        character(len=32) :: coeff_style = ''
        real(dp), allocatable :: coeff(:, :, :)       !< (2, i, j): epsilon, sigma
        logical, allocatable :: coeff_given(:, :)
        character(len=1024) :: notes = ''              !< sections skipped, for the screen
        logical :: ok = .true.
        character(len=8192) :: error = ''
    end type atom_table_t

    public :: bcast_atom_table, open_table_file

contains

    !> Open a text input of the table for reading; on failure t records '<path>: &system: <key>:
    !> cannot open the <what>' and ok is false.
    subroutine open_table_file(t, path, key, what, unit, ok)
        type(atom_table_t), intent(inout) :: t
        character(len=*), intent(in) :: path, key, what
        integer, intent(out) :: unit
        logical, intent(out) :: ok
        integer :: ios
        open (newunit=unit, file=path, status='old', action='read', iostat=ios)
        ok = ios == 0
        if (ok) return
        t%ok = .false.
        t%error = path//': &system: '//key//': cannot open the '//what
    end subroutine open_table_file

    !> Broadcast the table (and its error state) from rank 0 to all ranks.
    subroutine bcast_atom_table(t)
        use mpi_f08, only: MPI_Bcast, MPI_INTEGER, MPI_DOUBLE_PRECISION, MPI_LOGICAL, MPI_CHARACTER, &
                           MPI_INTEGER8
        use terrace_mpi_env, only: world
        type(atom_table_t), intent(inout) :: t
        integer :: head(2)
        logical :: flags(4)
        if (world%nprocs == 1) return
        head = [t%n, t%ntypes]
        flags = [t%has_box, t%has_velocities, t%has_masses, t%ok]
        call MPI_Bcast(head, 2, MPI_INTEGER, 0, world%comm)
        call MPI_Bcast(flags, 4, MPI_LOGICAL, 0, world%comm)
        call MPI_Bcast(t%error, len(t%error), MPI_CHARACTER, 0, world%comm)
        call MPI_Bcast(t%lo, 3, MPI_DOUBLE_PRECISION, 0, world%comm)
        call MPI_Bcast(t%hi, 3, MPI_DOUBLE_PRECISION, 0, world%comm)
        t%n = head(1); t%ntypes = head(2)
        t%has_box = flags(1); t%has_velocities = flags(2); t%has_masses = flags(3); t%ok = flags(4)
        if (.not. t%ok) return
        if (world%rank /= 0) then
            if (allocated(t%x)) deallocate (t%x, t%v, t%type, t%image, t%id, t%mass)
            allocate (t%x(3, t%n), t%v(3, t%n), t%type(t%n), t%image(3, t%n), t%id(t%n), t%mass(max(t%ntypes, 1)))
        end if
        if (t%n > 0) then
            call MPI_Bcast(t%x, 3*t%n, MPI_DOUBLE_PRECISION, 0, world%comm)
            call MPI_Bcast(t%v, 3*t%n, MPI_DOUBLE_PRECISION, 0, world%comm)
            call MPI_Bcast(t%type, t%n, MPI_INTEGER, 0, world%comm)
            call MPI_Bcast(t%image, 3*t%n, MPI_INTEGER, 0, world%comm)
            call MPI_Bcast(t%id, t%n, MPI_INTEGER8, 0, world%comm)
        end if
        call MPI_Bcast(t%mass, size(t%mass), MPI_DOUBLE_PRECISION, 0, world%comm)
    end subroutine bcast_atom_table

end module terrace_atom_table
