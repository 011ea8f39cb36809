!> The final state as an atoms file (`type x y z vx vy vz`, one line per atom in id order, full
!> precision), readable again through &system atoms_file: a small scene can be continued, or run
!> backwards with reverse_velocities (time-reversal checks). Gathered on rank 0: meant for small
!> scenes; periodic coordinates are wrapped into the box.
module terrace_final_atoms
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_box, only: box_t
    use terrace_mpi_env, only: world
    use mpi_f08, only: MPI_Gather, MPI_Gatherv, MPI_INTEGER, MPI_DOUBLE_PRECISION
    implicit none
    private

    public :: write_final_atoms

contains

    subroutine write_final_atoms(path, atoms, box, time, ok, msg)
        character(len=*), intent(in) :: path
        type(atoms_t), intent(in) :: atoms
        type(box_t), intent(in) :: box
        real(dp), intent(in) :: time
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        real(dp), allocatable :: mine(:, :), all(:, :)
        integer, allocatable :: counts(:), displs(:)
        integer :: n, total, r, i, j, unit, ios, d
        integer(i8) :: id
        ok = .true.; msg = ''
        n = atoms%nlocal
        allocate (mine(8, max(n, 1)))
        do i = 1, n
            mine(1, i) = real(atoms%id(i), dp)
            mine(2, i) = real(atoms%type(i), dp)
            mine(3:5, i) = atoms%x(:, i)
            do d = 1, box%dimension
                if (box%periodic(d)) mine(2 + d, i) = box%lo(d) + modulo(atoms%x(d, i) - box%lo(d), box%length(d))
            end do
            mine(6:8, i) = atoms%v(:, i)
        end do
        allocate (counts(world%nprocs), displs(world%nprocs))
        call MPI_Gather(8*n, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, 0, world%comm)
        total = 0
        if (world%rank == 0) then
            do r = 1, world%nprocs
                displs(r) = total; total = total + counts(r)
            end do
        end if
        allocate (all(8, max(total/8, 1)))
        call MPI_Gatherv(mine, 8*n, MPI_DOUBLE_PRECISION, all, counts, displs, MPI_DOUBLE_PRECISION, 0, world%comm)
        if (world%rank /= 0) return
        total = total/8
        open (newunit=unit, file=path, status='replace', action='write', iostat=ios, iomsg=msg)
        if (ios /= 0) then
            ok = .false.; return
        end if
        write (unit, '(a,es24.16e3)') '# terrace final state at time ', time
        write (unit, '(a)') '# type x y z vx vy vz   (one line per atom, in id order)'
        ! ids are 1..N for atoms files and lattices: place each line by id
        block
            integer, allocatable :: where(:)
            allocate (where(total))
            where = 0
            do j = 1, total
                id = nint(all(1, j), i8)
                if (id >= 1 .and. id <= total) where(id) = j
            end do
            do i = 1, total
                j = where(i)
                if (j == 0) cycle
                write (unit, '(i0,6(1x,es24.16e3))') nint(all(2, j)), all(3:8, j)
            end do
        end block
        close (unit)
    end subroutine write_final_atoms

end module terrace_final_atoms
