!> Per-atom forces written once (for checks against other codes): `# id fx fy fz`, sorted by id,
!> full precision. Gathered on rank 0: a diagnostic file, not a production output.
module terrace_forces_file
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_mpi_env, only: world
    use mpi_f08, only: MPI_Gather, MPI_Gatherv, MPI_INTEGER, MPI_INTEGER8, MPI_DOUBLE_PRECISION
    implicit none
    private

    public :: write_forces_file

contains

    subroutine write_forces_file(path, atoms, step, ok, msg)
        character(len=*), intent(in) :: path
        type(atoms_t), intent(in) :: atoms
        integer(i8), intent(in) :: step
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer, allocatable :: counts(:), displs(:), order(:)
        integer(i8), allocatable :: ids(:)
        real(dp), allocatable :: f(:, :)
        integer :: n, total, r, unit, ios, i
        ok = .true.; msg = ''
        n = atoms%nlocal
        allocate (counts(world%nprocs), displs(world%nprocs))
        call MPI_Gather(n, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, 0, world%comm)
        total = 0
        if (world%rank == 0) then
            do r = 1, world%nprocs
                displs(r) = total; total = total + counts(r)
            end do
        end if
        allocate (ids(max(total, 1)), f(3, max(total, 1)))
        call MPI_Gatherv(atoms%id, n, MPI_INTEGER8, ids, counts, displs, MPI_INTEGER8, 0, world%comm)
        call MPI_Gatherv(atoms%f, 3*n, MPI_DOUBLE_PRECISION, f, 3*counts, 3*displs, MPI_DOUBLE_PRECISION, 0, world%comm)
        if (world%rank /= 0) return
        allocate (order(total))
        order = [(i, i=1, total)]
        call sort_by_id(ids(1:total), order)
        open (newunit=unit, file=path, status='replace', action='write', iostat=ios, iomsg=msg)
        if (ios /= 0) then
            ok = .false.; return
        end if
        write (unit, '(a,i0)') '# terrace per-atom forces at step ', step
        write (unit, '(a)') '# id fx fy fz'
        do i = 1, total
            write (unit, '(i0,3(1x,es24.16e3))') ids(order(i)), f(:, order(i))
        end do
        close (unit)
    end subroutine write_forces_file

    !> Heap sort of an index array by id.
    subroutine sort_by_id(ids, order)
        integer(i8), intent(in) :: ids(:)
        integer, intent(inout) :: order(:)
        integer :: n, i, tmp
        n = size(order)
        do i = n/2, 1, -1
            call sift(i, n)
        end do
        do i = n, 2, -1
            tmp = order(1); order(1) = order(i); order(i) = tmp
            call sift(1, i - 1)
        end do
    contains
        subroutine sift(start, last)
            integer, intent(in) :: start, last
            integer :: root, child, t
            root = start
            do while (2*root <= last)
                child = 2*root
                if (child < last) then
                    if (ids(order(child + 1)) > ids(order(child))) child = child + 1
                end if
                if (ids(order(root)) >= ids(order(child))) return
                t = order(root); order(root) = order(child); order(child) = t
                root = child
            end do
        end subroutine sift
    end subroutine sort_by_id

end module terrace_forces_file
