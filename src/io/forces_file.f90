!> Per-atom forces written once (for checks against other codes): `# id fx fy fz`, sorted by id,
!> full precision. Gathered on rank 0: a diagnostic file, not a production output.
module terrace_forces_file
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_mpi_env, only: world
    use terrace_gather_by_id, only: gather_by_id
    use terrace_checked_text, only: checked_text_t
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
        integer :: i
        type(checked_text_t) :: out
        character(len=128) :: line
        ok = .true.; msg = ''
        call gather_by_id(atoms%nlocal, atoms%id(1:atoms%nlocal), atoms%f(:, 1:atoms%nlocal), ids, f)
        if (world%rank /= 0) return
        ! written under a temporary name, renamed over path when the run succeeds
        ! (terrace_output_files: commit_small_outputs); every write is checked (a full disk)
        call out%open(path, ok, msg)
        if (.not. ok) return
        write (line, '(a,i0)') '# terrace per-atom forces at step ', step
        call out%put(line, msg)
        call out%put('# id fx fy fz', msg)
        do i = 1, size(ids)
            if (out%ios /= 0) exit
            write (line, '(i0,3(1x,es24.16e3))') ids(i), f(:, i)
            call out%put(line, msg)
        end do
        call out%close(ok, msg)
    end subroutine write_forces_file

end module terrace_forces_file
