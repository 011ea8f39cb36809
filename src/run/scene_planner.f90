!> The scene plan's decisions, made once from the deck, the box, the atom count and the potential:
!> all pairs, cells + list (atom pairs or cluster pairs) or no list, and the lines that describe
!> the halo, pairs, potential, integrator and outputs (terrace_scene_plan holds and prints them).
module terrace_scene_planner
    use terrace_kinds, only: dp, i8
    use terrace_config, only: config_t
    use terrace_box, only: box_t
    use terrace_potential, only: potential_t
    use terrace_cluster_list, only: cluster_cutoff_limit
    use terrace_errors, only: stop_all
    use terrace_scene_plan, only: plan_t, pair_all, pair_cells, pair_none
    implicit none
    private

    public :: plan_scene

contains

    !> The decisions: all pairs, cells + list or no list (from what the potential supports, the
    !> deck's &neighbor list and the scene's size and boundaries), then the descriptions.
    subroutine plan_scene(self, cfg, box, natoms, nprocs, dims, pot)
        type(plan_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        type(box_t), intent(in) :: box
        integer(i8), intent(in) :: natoms
        integer, intent(in) :: nprocs, dims(3)
        class(potential_t), intent(in) :: pot
        self%natoms = natoms
        self%nprocs = nprocs
        self%dims = dims
        self%mesh = len_trim(cfg%mesh_file) > 0
        self%pair_mode = pair_cells
        if (pot%supports_all_pairs()) then
            if (cfg%list == 'all_pairs' .or. pot%cutoff() == 0) then
                self%pair_mode = pair_all
            else if (cfg%list == 'auto' .and. .not. any(box%periodic(1:cfg%dimension)) .and. &
                     natoms <= self%all_pairs_max) then
                self%pair_mode = pair_all
            end if
        else if (.not. pot%needs_pair_list()) then
            self%pair_mode = pair_none
        end if
        if (cfg%outer_skin > 0 .and. self%pair_mode /= pair_cells) call stop_all(cfg%where('neighbor', &
            trim(merge('prune_every', 'outer_skin ', cfg%prune_every > 0)))// &
            ': needs cell lists (this scene has no pair list or takes all pairs; allowed here: 0)')
        call describe_plan(self, cfg, box, pot)
    end subroutine plan_scene

    !> The plan's lines: halo and pairs, potential, integrator (with thermostat, barostat and
    !> minimization), outputs and box.
    subroutine describe_plan(self, cfg, box, pot)
        type(plan_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        type(box_t), intent(in) :: box
        class(potential_t), intent(in) :: pot
        character(len=512) :: s
        integer :: d
        call describe_pairs(self, cfg, box, pot)
        self%potential = pot%describe()
        call describe_integrator(self, cfg)
        self%outputs = 'screen'
        if (len_trim(cfg%thermo_file) > 0) self%outputs = self%outputs//', thermo CSV '//trim(cfg%thermo_file)
        if (len_trim(cfg%thermo_file) > 0 .and. len_trim(cfg%minimize) > 0) self%outputs = self%outputs// &
            ' (and the minimization rows beside it, .min before the extension)'
        if (len_trim(cfg%forces_file) > 0) self%outputs = self%outputs//', forces at step 0 '//trim(cfg%forces_file)
        if (len_trim(cfg%trajectory_file) > 0) self%outputs = self%outputs//', H5MD trajectory '// &
            trim(cfg%trajectory_file)//' ('//trim(cfg%trajectory_fields)//')'
        if (len_trim(cfg%checkpoint_file) > 0) self%outputs = self%outputs//', checkpoint '//trim(cfg%checkpoint_file)
        if (len_trim(cfg%final_atoms_file) > 0) self%outputs = self%outputs//', final atoms '// &
            trim(cfg%final_atoms_file)
        self%box = ''
        do d = 1, box%dimension
            write (s, '(a,1x,g0.8,a,g0.8,a)') 'xyz'(d:d)//':', box%lo(d), ' .. ', box%hi(d), &
                merge(' periodic;', ' free;    ', box%periodic(d))
            self%box = self%box//trim(s)//' '
        end do
    end subroutine describe_plan

    !> &neighbor outer_skin (velocity Verlet; config has checked the run): the list is built with
    !> outer_skin and the force pass reads the pairs within cutoff + skin pruned from it (inner_list),
    !> for potentials whose force pass allows a pruned list (Lennard-Jones) on cell lists: pruned when
    !> an atom has moved skin/2 (the exact list), or every prune_every steps (a fixed schedule; with
    !> buffer_tolerance both skins from the drift estimate).
    subroutine plan_outer_list(self, cfg, pot, s)
        type(plan_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        class(potential_t), intent(in) :: pot
        character(len=*), intent(inout) :: s
        character(len=32) :: v
        character(len=400) :: rule
        character(len=:), allocatable :: key
        key = trim(merge('prune_every', 'outer_skin ', cfg%prune_every > 0))
        if (.not. (pot%runs_on_pruned_list() .and. .not. pot%needs_full_neighbourhood(.false.))) &
            call stop_all(cfg%where('neighbor', key)//": only for Lennard-Jones styles (allowed with "// &
                          "style = '"//trim(cfg%potential)//"': 0)")
        write (v, '(g0.6)') cfg%skin
        if (.not. (cfg%outer_skin > cfg%skin)) call stop_all(cfg%where('neighbor', 'outer_skin')// &
            ': must be 0 (off) or > skin = '//trim(v)//' (a length in '//trim(cfg%units%length)//')')
        self%inner_list = .true.
        if (cfg%prune_every == 0) then
            rule = ' pruned from it when an atom has moved skin/2; rebuilt instead when at that step an atom has '// &
                   'moved (outer_skin - skin)/2 since the build'
        else
            write (rule, '(a,i0,a,i0,a)') ' pruned from it every ', cfg%prune_every, ' steps; rebuilt every ', &
                cfg%list_every, ' steps without a check'
            if (cfg%buffer_tolerance > 0) then
                write (v, '(es9.3)') cfg%buffer_tolerance
                rule = trim(rule)//', the skins sized for an energy drift of at most '//trim(v)//' '// &
                       trim(cfg%units%energy)//' per atom per '//trim(cfg%units%time)//', half each (&neighbor '// &
                       'buffer_tolerance;'
                write (v, '(es9.3)') max(cfg%buffer_drift, 0.0_dp)
                rule = trim(rule)//' estimate '//trim(v)//' for both'
                write (v, '(g0.5)') cfg%buffer_temperature
                rule = trim(rule)//', at T = '//trim(v)//')'
            end if
            rule = trim(rule)//' (not exact: pairs may be missed)'
        end if
        write (s, '(a,g0.6,a,g0.6,a,g0.6,a)') 'cell lists + half Verlet list, cutoff ', pot%cutoff(), &
            ' + outer_skin ', cfg%outer_skin, '; the force pass reads the pairs within cutoff + skin ', cfg%skin, &
            trim(rule)//'; atoms sorted by cell at each rebuild'
    end subroutine plan_outer_list

    !> The halo and pairs lines: all pairs, no pair list, or cells + list (atom pairs or cluster pairs).
    subroutine describe_pairs(self, cfg, box, pot)
        type(plan_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        type(box_t), intent(in) :: box
        class(potential_t), intent(in) :: pot
        character(len=800) :: s, rule
        character(len=64) :: half
        if (self%pair_mode == pair_all) then
            self%pairs = 'all pairs, no neighbour list (small or cutoff-free scene)'
            if (self%nprocs == 1) then
                self%halo = 'none (one rank)'
            else
                self%halo = 'replicated atoms (MPI_Allgatherv of positions every step)'
            end if
        else if (self%pair_mode == pair_none) then
            self%pairs = 'no pair list (the potential''s partners are fixed)'
            if (self%nprocs == 1) then
                self%halo = 'none (one rank)'
            else
                write (s, '(a,g0.6,a)') '6-way staged halo exchange (reach ', pot%halo_reach() + cfg%skin, &
                    ') with reverse force sums'
                self%halo = trim(s)
            end if
        else
            if (cfg%list_every == 1 .and. cfg%list_check) then
                rule = 'rebuilt when an atom has moved skin/2'
            else if (cfg%list_check) then
                write (rule, '(a,i0,a)') 'checked every ', cfg%list_every, &
                    ' steps and rebuilt when an atom has moved skin/2 (not exact: pairs may be missed)'
            else if (cfg%buffer_tolerance > 0) then
                write (rule, '(a,i0,a,es9.3,a,es9.3,a,g0.5,a)') 'rebuilt every ', cfg%list_every, ' steps without a '// &
                    'check, the skin sized for an energy drift of at most ', cfg%buffer_tolerance, ' '// &
                    trim(cfg%units%energy)//' per atom per '//trim(cfg%units%time)//' (&neighbor buffer_tolerance; '// &
                    'estimate ', max(cfg%buffer_drift, 0.0_dp), ' at T = ', cfg%buffer_temperature, '; pairs may be missed)'
            else
                write (rule, '(a,i0,a)') 'rebuilt every ', cfg%list_every, ' steps without a check (not exact: '// &
                    'pairs may be missed)'
            end if
            write (s, '(a,g0.6,a,g0.6,a)') 'cell lists + half Verlet list, cutoff ', pot%cutoff(), ' + skin ', cfg%skin, &
                ', '//trim(rule)//', atoms sorted by cell at each rebuild'
            self%inner_list = cfg%integ_style%exact_time .and. cfg%skin > 0 .and. &
                              pot%runs_on_pruned_list() .and. .not. pot%needs_full_neighbourhood(.true.)
            if (self%inner_list) s = trim(s)//'; force and ray passes over the pairs within cutoff + skin/4, '// &
                                     'pruned from it when an atom has moved skin/8'
            if (cfg%outer_skin > 0) call plan_outer_list(self, cfg, pot, s)
            self%cluster_pairs = cfg%list == 'clusters' .and. &
                                 pot%wants_clusters() .and. cfg%dimension == 3 .and. .not. self%inner_list
            ! an explicit 'clusters' the potential declines (config has checked precision and dimension; a
            ! cutoff at or beyond the cluster list's limit is left) is refused, where 'auto' takes the atom list
            if (cfg%list == 'clusters' .and. .not. self%cluster_pairs) then
                write (s, '(i0)') nint(cluster_cutoff_limit)
                call stop_all(cfg%where('neighbor', 'list')//" = 'clusters': needs &potential cutoff < "//trim(s)// &
                              " (length units; allowed with this cutoff: 'auto', 'cells', 'all_pairs')")
            end if
            if (self%cluster_pairs) then
                write (s, '(a,g0.6,a,g0.6,a)') 'cluster-pair list (clusters of 4 atoms in columns, pairs of clusters '// &
                    'with an atom pair within cutoff ', pot%cutoff(), ' + skin ', cfg%skin, '), '//trim(rule)// &
                    ', atoms sorted by cell at each rebuild; the mixed-precision kernel computes the 16 atom pairs '// &
                    'of each cluster pair'
            end if
            self%pairs = trim(s)
            self%wrap_images = self%nprocs == 1 .and. cfg%images == 'auto' .and. pot%wraps_images() .and. &
                               box%dimension == 3 .and. all(box%periodic) .and. .not. (self%cluster_pairs .or. &
                               cfg%integ_style%exact_time .or. cfg%barostat_couple == 'aniso') .and. &
                               2*(pot%cutoff() + max(cfg%skin, cfg%outer_skin)) < minval(box%length)
            self%half_images = self%nprocs == 1 .and. cfg%images == 'auto' .and. box%dimension == 3 .and. &
                               self%pair_mode == pair_cells .and. pot%runs_on_pruned_list() .and. .not. &
                               (self%cluster_pairs .or. pot%needs_full_neighbourhood(cfg%integ_style%exact_time))
            if (self%half_images) then
                half = 'half the periodic images (those the half list reads)'
            else
                half = 'periodic images'
            end if
            if (self%wrap_images) then
                self%halo = trim(half)//' copied on this rank at each list build only (no MPI); between '// &
                            'builds the force pass reads each as its owner at the nearest image: no copies '// &
                            'refreshed, no reverse force sums (&neighbor images)'
            else if (self%nprocs == 1) then
                if (any(box%periodic(1:box%dimension))) then
                    self%halo = trim(half)//' copied on this rank (no MPI)'
                else
                    self%halo = 'none (one rank, free boundaries)'
                end if
            else
                self%halo = '6-way staged halo exchange with reverse force sums (Newton across ghosts)'
            end if
        end if
    end subroutine describe_pairs

    !> The integrator line: the style (its time step, or how it advances without one), then the
    !> thermostat, barostat and minimization.
    subroutine describe_integrator(self, cfg)
        type(plan_t), intent(inout) :: self
        type(config_t), intent(in) :: cfg
        character(len=512) :: s
        if (len_trim(cfg%integ_style%plan_note) > 0) then
            s = trim(cfg%integrator)//' ('//trim(cfg%integ_style%plan_note)//')'
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
        if (cfg%barostat /= 'none' .and. len_trim(cfg%barostat) > 0) then
            write (s, '(a,g0.6,1x,a)') '; barostat '//trim(cfg%barostat)//' ('//trim(cfg%barostat_couple)// &
                '), P = ', cfg%barostat_pressure, trim(cfg%units%pressure)
            self%integrator = self%integrator//trim(s)
        end if
        if (len_trim(cfg%minimize) > 0) then
            write (s, '(a,g0.6,a,g0.6,a,i0,a,i0)') '; first minimized ('//trim(cfg%minimize)//', etol ', cfg%etol, &
                ', ftol ', cfg%ftol, ', at most ', cfg%max_iterations, ' iterations, ', cfg%max_evaluations
            s = trim(s)//' force evaluations'
            if (cfg%box_relax == 'iso' .or. cfg%box_relax == 'aniso') s = trim(s)//'; box relaxed ('// &
                                                                          trim(cfg%box_relax)//')'
            self%integrator = self%integrator//trim(s)//')'
        end if
    end subroutine describe_integrator

end module terrace_scene_planner
