!> The final state as an atoms file (`type x y z vx vy vz`, one line per atom in id order, full
!> precision), readable again through &system atoms_file: a small scene can be continued, or run
!> backwards with reverse_velocities (time-reversal checks). Gathered on rank 0: meant for small
!> scenes; periodic coordinates are wrapped into the box.
module terrace_final_atoms
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_box, only: box_t
    use terrace_mpi_env, only: world
    use terrace_gather_by_id, only: gather_atoms_by_id
    use terrace_checked_text, only: write_table
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
        real(dp), allocatable :: all(:, :)
        integer(i8), allocatable :: ids(:)
        integer :: i, d
        character(len=256) :: line
        ok = .true.; msg = ''
        call gather_atoms_by_id(atoms, .true., ids, all)
        if (world%rank /= 0) return
        ! positions in the periodic box
        do i = 1, size(ids)
            do d = 1, box%dimension
                if (box%periodic(d)) all(1 + d, i) = box%lo(d) + modulo(all(1 + d, i) - box%lo(d), box%length(d))
            end do
        end do
        write (line, '(a,es24.16e3)') '# terrace final state at time ', time
        call write_table(path, [character(len=256) :: line, '# type x y z vx vy vz   (one line per atom, in id order)'], &
                         nint(all(1, :), i8), all(2:7, :), ok, msg)
    end subroutine write_final_atoms

end module terrace_final_atoms
