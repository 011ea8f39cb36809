!> The start-up check that no two atoms sit on top of each other (what no potential survives).
module terrace_overlap_check
    use terrace_kinds, only: dp
    use terrace_atoms, only: atoms_t
    use terrace_neighbor_list, only: neighbor_list_t
    use terrace_potential, only: potential_t
    use terrace_scene_plan, only: pair_cells, pair_none
    use terrace_mpi_env, only: min_all
    use terrace_errors, only: check_all
    implicit none
    private

    public :: check_overlaps

contains

    !> Refuse a start with atoms on top of each other (closer than a quarter of the potential's
    !> contact distance, sigma for LJ).
    subroutine check_overlaps(atoms, list, pot, pair_mode, source)
        type(atoms_t), intent(in) :: atoms
        type(neighbor_list_t), intent(in) :: list
        class(potential_t), intent(in) :: pot
        integer, intent(in) :: pair_mode
        character(len=*), intent(in) :: source
        real(dp) :: rmin_ratio, rsq, sig
        integer :: i, k, j, jend
        character(len=32) :: s
        rmin_ratio = huge(1.0_dp)
        if (pair_mode == pair_none) return
        do i = 1, atoms%nlocal
            if (pair_mode == pair_cells) then
                k = list%first(i); jend = list%first(i + 1) - 1
            else
                k = i + 1; jend = atoms%nall()
            end if
            do while (k <= jend)
                if (pair_mode == pair_cells) then
                    j = list%neigh(k)
                else
                    j = k
                end if
                sig = pot%contact_distance(atoms%type(i), atoms%type(j))
                if (sig > 0) then
                    rsq = sum((atoms%x(:, i) - atoms%x(:, j))**2)
                    rmin_ratio = min(rmin_ratio, sqrt(rsq)/sig)
                end if
                k = k + 1
            end do
        end do
        call min_all(rmin_ratio)
        write (s, '(es10.3)') rmin_ratio
        call check_all(.not. (rmin_ratio < 0.25_dp), source//': overlapping atoms (closest pair '// &
                       'at '//trim(adjustl(s))//' sigma; at least sigma/4 is required)')
    end subroutine check_overlaps

end module terrace_overlap_check
