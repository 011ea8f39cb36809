!> The scene plan: what this run will compute and what it skips, decided once from the
!> configuration and the atom count, and printed by `terrace --check` and at the start of a run.
module terrace_scene_plan
    use terrace_kinds, only: dp, i8
    use terrace_config, only: config_t
    use terrace_box, only: box_t
    implicit none
    private

    integer, parameter, public :: pair_all = 1, pair_cells = 2

    type, public :: plan_t
        integer(i8) :: natoms = 0
        integer :: nprocs = 1
        integer :: dims(3) = 1
        integer :: pair_mode = pair_cells
        integer(i8) :: all_pairs_max = 64    !< 'auto' picks all pairs up to this many atoms (free scenes)
        character(len=:), allocatable :: halo, pairs, potential, integrator, outputs, box
    contains
        procedure :: finish => plan_finish
        procedure :: print => plan_print
    end type plan_t

contains

    subroutine plan_finish(self, cfg, box, cutmax)
        class(plan_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        type(box_t), intent(in) :: box
        real(dp), intent(in) :: cutmax
        character(len=512) :: s
        integer :: d
        if (self%pair_mode == pair_all) then
            self%pairs = 'all pairs, no neighbour list (small or cutoff-free scene)'
            if (self%nprocs == 1) then
                self%halo = 'none (one rank)'
            else
                self%halo = 'replicated atoms (MPI_Allgatherv of positions every step)'
            end if
        else
            write (s, '(a,g0.6,a,g0.6,a)') 'cell lists + half Verlet list, cutoff ', cutmax, ' + skin ', cfg%skin, &
                ', rebuilt when an atom has moved skin/2, atoms sorted by cell at each rebuild'
            self%pairs = trim(s)
            if (self%nprocs == 1) then
                if (any(box%periodic(1:box%dimension))) then
                    self%halo = 'periodic images copied on this rank (no MPI)'
                else
                    self%halo = 'none (one rank, free boundaries)'
                end if
            else
                self%halo = '6-way staged halo exchange with reverse force sums (Newton across ghosts)'
            end if
        end if
        if (cfg%potential(1:3) == 'eam') then
            self%potential = trim(cfg%potential)//' from '//trim(cfg%potential_file)// &
                             '; density pass, reverse sum of rho and forward halo of F''(rho)'
        else
            write (s, '(a,a,a,g0.6,a,g0.6)') trim(cfg%potential), trim(merge(' (shifted)', '          ', cfg%shift)), &
                ', epsilon(1,1) = ', cfg%epsilon(1, 1), ', sigma(1,1) = ', cfg%sigma(1, 1)
            self%potential = trim(s)//'; no density pass (pair potential)'
        end if
        if (cfg%integrator == 'energy_stepping') then
            s = 'energy_stepping (no time step: the next event decides; terrace height below)'
        else
            write (s, '(a,a,g0.6,1x,a)') trim(cfg%integrator), ', dt = ', cfg%dt, trim(cfg%units%time)
        end if
        self%integrator = trim(s)
        if (cfg%thermostat /= 'none') then
            write (s, '(a,g0.6,a,g0.6,1x,a,a,g0.6,1x,a)') '; thermostat '//trim(cfg%thermostat)//', T = ', &
                cfg%thermostat_temperature, ' -> ', cfg%thermostat_temperature_end, trim(cfg%units%temperature), &
                ', damping ', cfg%thermostat_damping, trim(cfg%units%time)
            self%integrator = self%integrator//trim(s)
        end if
        self%outputs = 'screen'
        if (len_trim(cfg%thermo_file) > 0) self%outputs = self%outputs//', thermo CSV '//trim(cfg%thermo_file)
        if (len_trim(cfg%forces_file) > 0) self%outputs = self%outputs//', forces at step 0 '//trim(cfg%forces_file)
        self%box = ''
        do d = 1, box%dimension
            write (s, '(a,1x,g0.8,a,g0.8,a)') 'xyz'(d:d)//':', box%lo(d), ' .. ', box%hi(d), &
                merge(' periodic;', ' free;    ', box%periodic(d))
            self%box = self%box//trim(s)//' '
        end do
    end subroutine plan_finish

    subroutine plan_print(self, unit)
        class(plan_t), intent(in) :: self
        integer, intent(in) :: unit
        write (unit, '(a,i0,a,i0,a,i0,a,i0,a,i0,a)') 'scene plan: ', self%natoms, ' atoms on ', self%nprocs, &
            ' rank(s), grid ', self%dims(1), ' x ', self%dims(2), ' x ', self%dims(3)
        write (unit, '(a)') '  box        : '//self%box
        write (unit, '(a)') '  pairs      : '//self%pairs
        write (unit, '(a)') '  halo       : '//self%halo
        write (unit, '(a)') '  potential  : '//self%potential
        write (unit, '(a)') '  integrator : '//self%integrator
        write (unit, '(a)') '  outputs    : '//self%outputs
    end subroutine plan_print

end module terrace_scene_plan
