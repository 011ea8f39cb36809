!> Per-atom forces written once (for checks against other codes): `# id fx fy fz`, sorted by id,
!> full precision. Gathered on rank 0: a diagnostic file, not a production output.
module terrace_forces_file
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_mpi_env, only: world
    use terrace_gather_by_id, only: gather_by_id
    use terrace_checked_text, only: write_table
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
        character(len=128) :: line
        ok = .true.; msg = ''
        call gather_by_id(atoms%nlocal, atoms%id(1:atoms%nlocal), atoms%f(:, 1:atoms%nlocal), ids, f)
        if (world%rank /= 0) return
        write (line, '(a,i0)') '# terrace per-atom forces at step ', step
        call write_table(path, [character(len=128) :: line, '# id fx fy fz'], ids, f, ok, msg)
    end subroutine write_forces_file

end module terrace_forces_file
