!> Per-atom forces written once (for checks against other codes): `# id fx fy fz`, sorted by id,
!> full precision. Gathered on rank 0: a diagnostic file, not a production output.
module terrace_forces_file
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_mpi_env, only: world
    use terrace_gather_by_id, only: gather_by_id
    use terrace_file_ops, only: temporary_name, remove_at_exit, check_size
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
        integer(i8), allocatable :: ids(:)
        real(dp), allocatable :: f(:, :)
        integer :: unit, ios, i, k
        integer(i8) :: bytes
        character(len=128) :: line
        ok = .true.; msg = ''
        bytes = 0; ios = 0
        call gather_by_id(atoms%nlocal, atoms%id(1:atoms%nlocal), atoms%f(:, 1:atoms%nlocal), ids, f)
        if (world%rank /= 0) return
        ! written under a temporary name, renamed over path when the run succeeds
        ! (terrace_output_files: commit_small_outputs); every write is checked (a full disk)
        open (newunit=unit, file=temporary_name(path), status='replace', action='write', iostat=ios, iomsg=msg)
        if (ios /= 0) then
            ok = .false.; return
        end if
        call remove_at_exit(temporary_name(path))
        write (line, '(a,i0)') '# terrace per-atom forces at step ', step
        call put(line)
        call put('# id fx fy fz')
        do i = 1, size(ids)
            if (ios /= 0) exit
            write (line, '(i0,3(1x,es24.16e3))') ids(i), f(:, i)
            call put(line)
        end do
        if (ios == 0) then
            ! closed in any case; a short file (full disk) is removed at exit
            close (unit, iostat=ios, iomsg=msg)
            if (ios == 0) call check_size(temporary_name(path), bytes, ok, msg)
            if (ios == 0 .and. .not. ok) ios = -1
        else
            close (unit, status='delete', iostat=k)
        end if
        ok = ios == 0
    contains
        subroutine put(text)
            character(len=*), intent(in) :: text
            if (ios /= 0) return
            write (unit, '(a)', iostat=ios, iomsg=msg) trim(text)
            bytes = bytes + len_trim(text) + 1
        end subroutine put
    end subroutine write_forces_file

end module terrace_forces_file
