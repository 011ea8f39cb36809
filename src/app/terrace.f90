!> terrace: the molecular-dynamics engine.
!>   terrace RUN.nml            run the namelist input
!>   terrace --check RUN.nml    read, validate and print the scene plan; run nothing, write nothing
!>   terrace --version | --help
program terrace
    use terrace_kinds, only: dp, i8
    use terrace_text, only: fixed
    use terrace_mpi_env, only: world, start_mpi, end_mpi, any_all, sum_all_i8
    use terrace_config, only: config_t, read_config
    use terrace_engine, only: engine_t
    use terrace_scene_builder, only: scene_t, build_scene
    use terrace_thermo, only: thermo_writer_t
    use terrace_schedule, only: schedule_t
    use terrace_run_schedule, only: make_schedule
    use terrace_run_params, only: engine_params, control_params, verlet_params, es_params, ed_params, make_thermostat, &
                                  make_barostat, minimize_params
    use terrace_thermostat, only: thermostat_t
    use terrace_barostat, only: barostat_t
    use terrace_minimize, only: run_minimize, minimize_result_t, no_unit
    use terrace_velocity_verlet, only: run_velocity_verlet
    use terrace_energy_stepping, only: run_energy_stepping, choose_terrace_height, print_es_estimates, es_stats_t, &
                                       es_thermo_header
    use terrace_velocities, only: kinetic_energy
    use terrace_event_driven, only: run_event_driven, ed_params_t, ed_stats_t, ed_thermo_header, check_event_driven_start
    use terrace_forces_file, only: write_forces_file
    use terrace_final_atoms, only: write_final_atoms
    use terrace_trajectory, only: trajectory_t
    use terrace_run_log, only: print_run_log
    use terrace_errors, only: stop_all, check_all
    use terrace_version, only: terrace_version_string
    use terrace_info_flags, only: answer_info_flag
    use terrace_run_control, only: run_control_t
    use terrace_run_outputs, only: run_outputs_t
    use terrace_run_parts, only: run_parts_t
    use terrace_signals, only: exit_stopped
    use terrace_checkpoint, only: probe_checkpoint_path
    use terrace_output_files, only: check_outputs, check_output_ids, commit_small_outputs
    use terrace_memory_guard, only: check_memory
    use terrace_files, only: part_path
    use mpi_f08, only: MPI_Wtime, MPI_Barrier
    use, intrinsic :: iso_fortran_env, only: output_unit
    use terrace_run_summary, only: summary_put, summary_start, summary_write
    use terrace_xdmf, only: xdmf_sidecar_path
    use terrace_topology_data, only: topology_data_path, wants_topology_data, write_topology_data
    implicit none

    type(config_t) :: cfg
    type(engine_t), target :: eng
    type(scene_t) :: scene
    type(thermo_writer_t), target :: thermo
    type(trajectory_t), target :: traj
    type(schedule_t) :: sched
    class(thermostat_t), allocatable, target :: ts
    class(barostat_t), allocatable, target :: bs
    character(len=:), allocatable :: path
    character(len=4096) :: arg
    logical :: check_only, ok
    integer :: k
    !> Energy stepping: the run log warns when more than half of at least this many events were reflections.
    integer, parameter :: min_events_share = 100
    real(dp) :: t0, t1, h
    type(es_stats_t) :: es
    character(len=512) :: msg
    type(run_control_t), target :: ctl
    type(run_outputs_t), target :: out
    real(dp) :: wall_start

    call start_mpi()
    wall_start = MPI_Wtime()
    check_only = .false.
    path = ''
    do k = 1, command_argument_count()
        call get_command_argument(k, arg)
        call answer_info_flag(arg, 'terrace', print_help)
        select case (trim(arg))
        case ('--check')
            check_only = .true.
        case default
            if (arg(1:1) == '-') call stop_all("unknown option '"//trim(arg)//"' (see terrace --help)", 2)
            if (len(path) > 0) call stop_all('give one input file (see terrace --help)', 2)
            path = trim(arg)
        end select
    end do
    if (len(path) == 0) call stop_all('no input file (usage: terrace [--check] RUN.nml; see terrace --help)', 2)

    call read_config(path, cfg)
    call summary_start(path)
    call check_memory(cfg)                              ! refuse a scene that cannot fit
    if (.not. check_only) call ctl%init_signals(trim(cfg%checkpoint_file))
    call build_scene(cfg, scene)
    call eng%setup(engine_params(cfg), scene)
    sched = make_schedule(cfg)
    call make_thermostat(cfg, eng%natoms, sched, ts)
    eng%ndof = ts%dof
    call make_barostat(cfg, eng%natoms, bs)
    call check_outputs(cfg, lock=.not. check_only)      ! outputs checked (and locked) before any is opened
    call check_output_ids(cfg, eng%atoms%id(1:eng%atoms%nlocal), eng%natoms)
    if (world%rank == 0) call eng%plan%print(output_unit)
    if (len_trim(cfg%minimize) > 0 .and. .not. check_only .and. .not. eng%restarted) call minimize_run()

    if (cfg%integ_style%exact_time) then
        call energy_stepping_run()
    else if (cfg%integ_style%event_driven) then
        call event_driven_run()
    else
        call verlet_run()
    end if
    call end_mpi()

contains

    subroutine verlet_run()
        if (check_only) then
            if (world%rank == 0) write (output_unit, '(a,i0,a,i0,a)') '  run        : ', sched%n_steps, &
                ' steps, thermo every ', sched%thermo_every, ' steps'
            call finish_check()
        end if
        call open_outputs(trim(merge(',vol,box_lx,box_ly,box_lz', '                         ', bs%active()))// &
                          trim(merge(',ecouple,econserve', '                  ', cfg%thermostat /= 'none')), &
                          sched%end_time())
        call start_clock()
        call run_velocity_verlet(run_parts_t(eng=eng, ts=ts, bs=bs, out=out), verlet_params(cfg), sched)
        call close_run(sched%end_time())
        call print_run_log(eng%timers, t1 - t0, eng%natoms, sched%n_steps, eng%list%builds, 'steps', &
                           joined(schedule_note(), prune_note()), list_pairs(), pairs_what())
        call eng%report_warnings()
        if (.not. eng%list%exact()) call summary_put('neighbor/late_builds', eng%list%late)
        if (eng%outer_list) call summary_put('neighbor/prunes', eng%prunes)
        if (eng%outer_list) call summary_put('neighbor/outer_skin', cfg%outer_skin)
        if (eng%prune_every > 0) call summary_put('neighbor/prune_every', eng%prune_every)
        call write_summary('finished', sched%end_time())
    end subroutine verlet_run

    !> The deck's minimization before the dynamics: its rows in <thermo_file stem>.min.csv (when
    !> a thermo file is written), the stopping criterion and energies on the screen.
    subroutine minimize_run()
        type(minimize_result_t) :: res
        integer :: unit, dot
        character(len=:), allocatable :: min_path
        logical :: there
        unit = no_unit
        there = .false.
        min_path = ''
        if (len_trim(cfg%thermo_file) > 0) then
            dot = index(trim(cfg%thermo_file), '.', back=.true.)
            if (dot > index(trim(cfg%thermo_file), '/', back=.true.)) then
                min_path = cfg%thermo_file(1:dot - 1)//'.min'//trim(cfg%thermo_file(dot:))
            else
                min_path = trim(cfg%thermo_file)//'.min.csv'
            end if
            if (world%rank == 0) inquire (file=min_path, exist=there)
            call any_all(there)
            call check_all(.not. there .or. cfg%overwrite, min_path//': exists (the minimization rows of '// &
                           cfg%where('output', 'thermo_file')//'); set &output overwrite = .true. to replace it')
            if (world%rank == 0) open (newunit=unit, file=min_path, status='replace', action='write')
        end if
        call run_minimize(eng, minimize_params(cfg), unit, res)
        if (unit /= no_unit) close (unit)
        if (world%rank == 0) then
            write (output_unit, '(a)') 'Minimization ('//trim(cfg%minimize)//'): stopping criterion = '//res%criterion
            write (output_unit, '(a,i0,a,i0)') '  iterations, force evaluations = ', res%iterations, ' ', res%evaluations
            write (output_unit, '(a,es24.16,1x,es24.16)') '  energy initial, final = ', res%e_initial, res%e_final
            write (output_unit, '(a,es12.5,1x,es12.5)') '  force two-norm, max component = ', res%fnorm2, res%fmax
            if (len_trim(cfg%box_relax) > 0 .and. cfg%box_relax /= 'none') &
                write (output_unit, '(a,i0,a,es24.16,a,3es24.16)') '  box relaxed: ', res%box_steps, &
                trim(merge(' volume steps; pressure ', ' box steps; pressure    ', cfg%box_relax == 'iso'))//' ', &
                res%pressure, ' ; box lengths ', eng%box%length
            if (cfg%box_relax == 'aniso') write (output_unit, '(a,3es24.16)') &
                '  pressure diagonal ', res%pressure_diag
            flush (output_unit)
        end if
    end subroutine minimize_run

    !> This rank's pairs in the built list (within rc + skin) at its last build; 0 without a list.
    integer(i8) function list_pairs()
        list_pairs = 0
        if (eng%list%want_clusters) then
            list_pairs = eng%list%clusters%pairs%npairs
            return
        end if
        if (eng%list%builds == 0 .or. eng%list%all_pairs .or. .not. allocated(eng%list%first)) return
        if (size(eng%list%first) < eng%atoms%nlocal + 1) return
        list_pairs = eng%list%first(eng%atoms%nlocal + 1) - 1
    end function list_pairs

    !> What list_pairs counts, for the run log ('': the atom list's pairs).
    function pairs_what() result(what)
        character(len=:), allocatable :: what
        what = ''
        if (eng%list%want_clusters) what = 'Cluster pairs (clusters of 4 atoms with an atom pair within rc + skin, '// &
                                           'last build; the mixed kernel computes 16 atom pairs each)'
        if (eng%outer_list) what = 'List pairs (within rc + outer_skin, last build)'
    end function pairs_what

    !> The run log's line on the pruned list of energy stepping or of velocity Verlet's outer_skin
    !> (empty without one).
    function prune_note() result(note)
        character(len=:), allocatable :: note
        character(len=256) :: line
        note = ''
        if (.not. eng%use_inner) return
        if (eng%outer_list) then
            write (line, '(a,es9.3,a,es9.3,a,i0,a)') 'Pruned list (pairs within rc + skin = rc + ', eng%inner%skin, &
                ', used by the force pass; built list: rc + outer_skin = rc + ', eng%list%skin, '): ', eng%prunes, &
                ' prunes between the builds'
        else
            write (line, '(a,es9.3,a,i0,a)') 'Pruned list (pairs within rc + skin/4 = rc + ', eng%inner%skin, &
                ', used by the force and ray passes): ', eng%prunes, ' prunes'
        end if
        note = trim(line)
    end function prune_note

    !> Two notes of the run log, one to a line (either may be empty).
    function joined(a, b) result(note)
        character(len=*), intent(in) :: a, b
        character(len=:), allocatable :: note
        note = a
        if (len(a) > 0 .and. len(b) > 0) note = note//new_line('a')
        note = note//b
    end function joined

    !> The run log's line on a neighbour-list schedule that is not the exact one (empty otherwise).
    function schedule_note() result(note)
        character(len=:), allocatable :: note
        character(len=256) :: line
        note = ''
        if (eng%list%exact()) return
        write (line, '(a,i0,a,a,a,i0,a,i0)') 'Neighbour list schedule: every ', eng%list%every, ' steps, ', &
            trim(merge('checked ', 'no check', eng%list%check)), '; builds at which an atom had moved more than skin/2: ', &
            eng%list%late, ' of ', eng%list%builds
        note = trim(line)
        if (eng%list%late > 0) note = note//new_line('a')//'  (the list had passed its skin/2 guarantee before each '// &
                                      'of those: pairs within the cutoff may have been missed)'
        if (eng%list%late > 0 .and. cfg%buffer_tolerance > 0) note = note//new_line('a')//'  (expected with '// &
            '&neighbor buffer_tolerance: its skin bounds the estimated energy drift of the missed pairs, not the '// &
            'displacement; compare the energy drift above with the tolerance)'
    end function schedule_note

    subroutine energy_stepping_run()
        real(dp) :: ke
        character(len=32) :: s1, s2
        if (eng%restarted) then
            ok = .true.
            h = eng%restart_values%get_r('h', ok)
            call check_all(ok, trim(cfg%read_checkpoint)//': &system: read_checkpoint: damaged checkpoint (no h)')
        else
            h = choose_terrace_height(eng, es_params(cfg))
        end if
        ke = kinetic_energy(eng%atoms, cfg%units)
        if (h > abs(eng%pe) + ke .and. .not. eng%restarted) then
            write (s1, '(es12.5)') h
            write (s2, '(es12.5)') abs(eng%pe) + ke
            call stop_all(cfg%where('integrator', 'terrace_height')//' = '//trim(adjustl(s1))// &
                          ': larger than the whole energy range of the system (|V| + K = '//trim(adjustl(s2))//')')
        end if
        ! a terrace below the round-off of V cannot be resolved: the event search would stall
        if (h < 1.0e3_dp*epsilon(1.0_dp)*(abs(eng%pe) + ke) .and. .not. eng%restarted) then
            write (s1, '(es12.5)') h
            write (s2, '(es12.5)') 1.0e3_dp*epsilon(1.0_dp)*(abs(eng%pe) + ke)
            call stop_all(cfg%where('integrator', trim(merge('terrace_height', 'target_mean_dt', &
                          cfg%terrace_height > 0)))//': the terrace height '//trim(adjustl(s1))//' is below the '// &
                          'round-off of the energy (|V| + K) of this system; the events could not be resolved '// &
                          '(allowed: a terrace height of at least '//trim(adjustl(s2))//' '//trim(cfg%units%energy)//')')
        end if
        call print_es_estimates(eng, h)
        if (check_only) then
            if (world%rank == 0) then
                if (cfg%run_time > 0) then
                    write (output_unit, '(a,es12.5,1x,a)') '  run        : until t = ', sched%t_end, trim(cfg%units%time)
                else
                    write (output_unit, '(a,i0,a)') '  run        : ', sched%n_steps, ' events'
                end if
            end if
            call finish_check()
        end if
        call open_outputs(es_thermo_header//trim(merge(',vol,box_lx,box_ly,box_lz', '                         ', &
                                                        bs%active()))// &
                          trim(merge(',ecouple,econserve', '                  ', cfg%thermostat /= 'none')), &
                          sched%end_time())
        call start_clock()
        call run_energy_stepping(run_parts_t(eng=eng, ts=ts, bs=bs, out=out), es_params(cfg), h, sched, es)
        call close_run(es%time)
        call print_run_log(eng%timers, t1 - t0, eng%natoms, es%events, eng%list%builds, 'events', prune_note(), &
                           list_pairs())
        if (world%rank == 0) then
            write (output_unit, '(a,i0,a,i0,a,i0,a,i0,a)') 'Events: ', es%events, ' (', es%ups, ' up, ', es%downs, &
                ' down, ', es%reflections, ' reflections)'
            if (es%events > 0) write (output_unit, '(a,es12.5,a,i0)') 'Mean event interval: ', &
                es%time/es%events, ' '//trim(cfg%units%time)//';  ray evaluations per event: '// &
                fixed(real(es%ray_evals, dp)/es%events, 3)// &
                ';  force passes per event: '//fixed(real(es%force_passes, dp)/es%events, 3)// &
                ';  verification misses: ', es%verify_misses
            if (es%have_conserved) write (output_unit, '(a,es17.10,a,es17.10,a,es10.3,a)') &
                'Conserved K + k h (first, last thermo sample, '//trim(cfg%units%energy)//'): ', es%conserved_first, &
                ', ', es%conserved_last, '; drift ', es%conserved_last - es%conserved_first, &
                ' (round-off; K + V stays within h of it)'
            if (es%events >= min_events_share .and. es%reflections > 0.5_dp*es%events) then
                write (s1, '(f5.1)') 100.0_dp*real(es%reflections, dp)/es%events
                if (es%reflections > 0.9_dp*es%events) then
                    write (output_unit, '(a)') 'terrace: warning: '//trim(adjustl(s1))//' % of the events were '// &
                        'reflections: the state is trapped below a terrace edge (its climbs never carry enough '// &
                        'kinetic energy across it), so kinetic and potential energy no longer exchange. Use a '// &
                        'smaller terrace_height.'
                else
                    write (output_unit, '(a)') 'terrace: warning: '//trim(adjustl(s1))//' % of the events were '// &
                        'reflections (more than half): most climbs fall short of the next terrace, kinetic and '// &
                        'potential energy exchange slowly and the trajectory is coarse. Use a smaller terrace_height '// &
                        '(doc/choosing_an_integrator.md).'
                end if
            end if
        end if
        call summary_es()
        call write_summary('finished', es%time)
    end subroutine energy_stepping_run

    !> Event-driven dynamics of a stepped potential: until run_time, thermo samples every
    !> thermo_interval (default run_time / 10), frames every trajectory_interval (default: at the
    !> samples), all at exact times.
    subroutine event_driven_run()
        type(ed_stats_t) :: ed
        type(ed_params_t) :: p
        p = ed_params(cfg)
        call check_event_driven_start(eng, p)
        if (check_only) then
            if (world%rank == 0) write (output_unit, '(a,es12.5,1x,a)') '  run        : event-driven until t = ', &
                cfg%run_time, trim(cfg%units%time)
            call finish_check()
        end if
        call open_outputs(ed_thermo_header//trim(merge(',ecouple,econserve', '                  ', &
                                                       cfg%thermostat /= 'none')), cfg%run_time)
        call start_clock()
        call run_event_driven(run_parts_t(eng=eng, ts=ts, bs=bs, out=out), p, ed)
        call close_run(cfg%run_time)
        call print_run_log(eng%timers, t1 - t0, eng%natoms, ed%events, eng%list%builds, 'events')
        if (world%rank == 0) then
            write (output_unit, '(a,i0,a,i0,a,i0,a,i0,a)') 'Events: ', ed%events, ' (', ed%pair_events, &
                ' pair crossings, ', ed%cell_events, ' cell crossings, ', ed%stale, ' stale predictions)'
            write (output_unit, '(a,i0,a,i0,a,i0,a,i0,a)') 'Pair crossings: ', ed%core, ' hard-core collisions, ', &
                ed%captures, ' captures, ', ed%escapes, ' escapes, ', ed%bounces, ' bounces'
            if (t1 > t0) write (output_unit, '(a,es11.4,a,es11.4,a,es11.4,a)') 'Event rate: ', ed%events/(t1 - t0), &
                ' events/s, ', ed%pair_events/(t1 - t0), ' pair crossings/s; ', (t1 - t0)/max(1_i8, ed%events)*1.0e6_dp, &
                ' us per event'
            write (output_unit, '(a,es17.10,a,es17.10,a,es10.3)') 'Total energy'// &
                trim(merge(' less ecouple', '             ', cfg%thermostat /= 'none'))// &
                ' (first, last thermo sample, '//trim(cfg%units%energy)//'): ', ed%e_first, ', ', ed%e_last, &
                '; drift ', ed%e_last - ed%e_first
        end if
        call summary_put('event_driven/', [character(len=20) :: 'events', 'pair_crossings', 'cell_crossings', &
                         'stale_predictions', 'hard_core_collisions', 'captures', 'escapes', 'bounces'], &
                         [ed%events, ed%pair_events, ed%cell_events, ed%stale, ed%core, ed%captures, ed%escapes, &
                          ed%bounces])
        if (t1 > t0) call summary_put('event_driven/events_per_second', ed%events/(t1 - t0))
        call summary_put('conservation/energy_first', ed%e_first)
        call summary_put('conservation/energy_last', ed%e_last)
        call summary_put('conservation/energy_drift', ed%e_last - ed%e_first)
        call write_summary('finished', cfg%run_time)
    end subroutine event_driven_run

    !> Energy stepping's closing figures in the run summary.
    subroutine summary_es()
        call summary_put('energy_stepping/terrace_height', h)
        call summary_put('energy_stepping/events', es%events)
        call summary_put('energy_stepping/ups', es%ups)
        call summary_put('energy_stepping/downs', es%downs)
        call summary_put('energy_stepping/reflections', es%reflections)
        if (es%events > 0) then
            call summary_put('energy_stepping/reflection_share', real(es%reflections, dp)/es%events)
            call summary_put('energy_stepping/mean_event_interval', es%time/es%events)
            call summary_put('energy_stepping/ray_evaluations_per_event', real(es%ray_evals, dp)/es%events)
            call summary_put('energy_stepping/force_passes_per_event', real(es%force_passes, dp)/es%events)
        end if
        call summary_put('energy_stepping/verification_misses', es%verify_misses)
        if (es%have_conserved) then
            call summary_put('energy_stepping/conserved_first', es%conserved_first)
            call summary_put('energy_stepping/conserved_last', es%conserved_last)
            call summary_put('energy_stepping/conserved_drift', es%conserved_last - es%conserved_first)
        end if
        if (eng%use_inner) call summary_put('neighbor/prunes', eng%prunes)
    end subroutine summary_es

    !> The run summary (&output summary_file, src/io/run_summary.f90): what ran, where, in which
    !> units, what it wrote and how it ended, with the figures the run log put there. Collective.
    subroutine write_summary(reason, sim_time)
        character(len=*), intent(in) :: reason
        real(dp), intent(in), optional :: sim_time   !< absent after an early stop (see checkpoint/time)
        logical :: there
        if (len_trim(cfg%summary_file) == 0) return
        call summary_put('units/style', trim(cfg%units%name))
        call summary_put('units/length', trim(cfg%units%length))
        call summary_put('units/time', trim(cfg%units%time))
        call summary_put('units/energy', trim(cfg%units%energy))
        call summary_put('units/mass', trim(cfg%units%mass))
        call summary_put('units/temperature', trim(cfg%units%temperature))
        call summary_put('units/pressure', trim(cfg%units%pressure))
        call summary_put('units/velocity', trim(cfg%units%velocity))
        call summary_put('run/integrator', trim(cfg%integrator))
        call summary_put('run/thermostat', trim(cfg%thermostat))
        call summary_put('run/dimension', cfg%dimension)
        call summary_put('run/atoms', eng%natoms)
        call summary_put('run/restarted', eng%restarted)
        if (present(sim_time)) call summary_put('run/simulated_time', sim_time)
        if (eng%list%builds > 0) call summary_put('neighbor/skin', cfg%skin)
        call summary_put('timing/loop_time_s', t1 - t0)
        call summary_put('exit/reason', reason)
        call summary_put('exit/status', merge(exit_stopped, 0, reason /= 'finished'))
        if (reason /= 'finished') call summary_put('exit/detail', ctl%reason)
        if (len_trim(cfg%thermo_file) > 0) call summary_put('outputs/thermo_file', part_path(trim(cfg%thermo_file), &
                                                             int(ctl%output_part, i8)))
        if (len_trim(cfg%trajectory_file) > 0) then
            call summary_put('outputs/trajectory_file', part_path(trim(cfg%trajectory_file), int(ctl%output_part, i8)))
            if (allocated(eng%mesh_tet)) call summary_put('outputs/xdmf_file', &
                xdmf_sidecar_path(part_path(trim(cfg%trajectory_file), int(ctl%output_part, i8))))
            if (wants_topology_data(cfg%trajectory_file, cfg%dimension, allocated(eng%mesh_tet))) &
                call summary_put('outputs/topology_file', &
                                 topology_data_path(part_path(trim(cfg%trajectory_file), int(ctl%output_part, i8))))
        end if
        if (len_trim(cfg%forces_file) > 0 .and. .not. eng%restarted) call summary_put('outputs/forces_file', &
                                                                                     trim(cfg%forces_file))
        if (len_trim(cfg%final_atoms_file) > 0 .and. reason == 'finished') &
            call summary_put('outputs/final_atoms_file', trim(cfg%final_atoms_file))
        if (len_trim(cfg%checkpoint_file) > 0) then
            inquire (file=trim(cfg%checkpoint_file), exist=there)
            if (there) call summary_put('outputs/checkpoint_file', trim(cfg%checkpoint_file))
        end if
        ! (a run that goes on in part files, &system restart_outputs = 'new', writes its summary as one too)
        call summary_put('outputs/summary_file', part_path(trim(cfg%summary_file), int(ctl%output_part, i8)))
        call summary_write(part_path(trim(cfg%summary_file), int(ctl%output_part, i8)), ok, msg)
        call check_all(ok, part_path(trim(cfg%summary_file), int(ctl%output_part, i8))// &
                       ': cannot write (&output summary_file): '//trim(msg))
    end subroutine write_summary

    !> Timers and wall clock start together on every rank; the integrator writes through `out`.
    subroutine start_clock()
        out%thermo => thermo
        thermo%progress_seconds = cfg%progress_seconds
        if (sched%n_steps > 0 .and. sched%n_steps < huge(1_i8)) thermo%end_step = sched%n_steps
        out%traj => traj
        out%ctl => ctl
        out%thermostat = ts%active()
        call MPI_Barrier(world%comm)
        call eng%timers%reset()
        t0 = MPI_Wtime()
    end subroutine start_clock

    !> After the integrator: the wall clock stops, the outputs are closed, the final state written
    !> and the small outputs committed (replaced only on success), or the early stop reported.
    subroutine close_run(end_time)
        real(dp), intent(in) :: end_time
        call MPI_Barrier(world%comm)
        t1 = MPI_Wtime()
        call thermo%close()
        call traj%close(ok, msg)
        call check_all(ok, trim(cfg%trajectory_file)//': &output trajectory_file: '//trim(msg))
        if (ctl%stopped) call stop_early()
        call write_final(end_time)
        call commit_small_outputs(cfg)
    end subroutine close_run

    !> The run stopped early with a checkpoint (walltime_limit or a signal): say so and exit with
    !> exit_stopped on every rank, so that a batch script can resubmit it with read_checkpoint.
    subroutine stop_early()
        call commit_small_outputs(cfg)                  ! what was written so far is kept
        call write_summary(trim(merge('walltime_limit', 'signal        ', ctl%stop_signal == 0)))
        if (world%rank == 0) then
            write (output_unit, '(a)') 'terrace: stopped early ('//ctl%reason//') with a checkpoint in '//ctl%path// &
                '; continue with &system read_checkpoint = '''//ctl%path//''' (exit status 3)'
            flush (output_unit)
        end if
        call end_mpi()
        stop exit_stopped, quiet=.true.
    end subroutine stop_early

    subroutine write_final(time)
        real(dp), intent(in) :: time
        if (len_trim(cfg%final_atoms_file) == 0) return
        call write_final_atoms(trim(cfg%final_atoms_file), eng%atoms, eng%box, time, ok, msg)
        call check_all(ok, trim(cfg%final_atoms_file)//': cannot write (&output final_atoms_file): '//trim(msg))
    end subroutine write_final

    subroutine finish_check()
        if (world%rank == 0) write (output_unit, '(a)') 'check: OK ('//path//')'
        call end_mpi()
        stop
    end subroutine finish_check

    subroutine open_outputs(extra_header, end_time)
        character(len=*), intent(in) :: extra_header
        real(dp), intent(in) :: end_time
        call ctl%init(control_params(cfg), eng, wall_start)
        if (ctl%active) then
            call probe_checkpoint_path(trim(cfg%checkpoint_file), ok, msg)
            call check_all(ok, cfg%where('output', 'checkpoint_file')//" = '"//trim(cfg%checkpoint_file)//"': "// &
                           trim(msg))
        end if
        if (eng%restarted) then
            call open_outputs_append(extra_header, end_time)
            return
        end if
        call create_outputs(trim(cfg%trajectory_file), trim(cfg%thermo_file), extra_header, end_time)
        if (len_trim(cfg%forces_file) > 0) then
            call write_forces_file(trim(cfg%forces_file), eng%atoms, 0_i8, ok, msg)
            call any_failed(ok)
            if (.not. ok) then
                call thermo%discard()
                call traj%discard()
            end if
            call check_all(ok, trim(cfg%forces_file)//': cannot write the forces file (&output forces_file): '//trim(msg))
        end if
    end subroutine open_outputs

    !> A new thermo CSV and trajectory (and a mesh's XDMF sidecar) under these names. A failure
    !> after the trajectory was created removes what was written: no partial outputs.
    subroutine create_outputs(traj_path, thermo_path, extra_header, end_time)
        character(len=*), intent(in) :: traj_path, thermo_path, extra_header
        real(dp), intent(in) :: end_time
        call traj%open(traj_path, trim(cfg%trajectory_fields), world%comm, eng%natoms, eng%box, eng%atoms%mass, &
                       cfg%units, ok, msg)
        call check_all(ok, traj_path//': cannot create the trajectory (&output trajectory_file): '//trim(msg))
        if (allocated(eng%mesh_tet)) then        ! a mesh: its tetrahedra and the XDMF sidecar
            call traj%add_mesh(eng%mesh_tet, eng%natoms, ok, msg)
            if (.not. ok) call traj%discard()
            call check_all(ok, traj_path//': cannot create the trajectory (&output trajectory_file): '//trim(msg))
        end if
        call thermo%open(thermo_path, end_time, trim(cfg%units%time), extra_header, ok, msg, units=cfg%units, &
                         mesh=allocated(eng%mesh_tet))
        call any_failed(ok)
        if (.not. ok) call traj%discard()
        call check_all(ok, thermo_path//': cannot write the thermo file (&output thermo_file): '//trim(msg))
        call create_topology_data(traj_path)
    end subroutine create_outputs

    !> Beside a 3-D trajectory, its topology for MDAnalysis (src/io/topology_data.f90).
    subroutine create_topology_data(traj_path)
        character(len=*), intent(in) :: traj_path
        if (.not. wants_topology_data(traj_path, cfg%dimension, allocated(eng%mesh_tet))) return
        call write_topology_data(traj_path, eng%atoms, eng%box, trim(cfg%units%name), terrace_version_string, ok, msg)
        call any_failed(ok)
        if (.not. ok) then
            call thermo%discard()
            call traj%discard()
        end if
        call check_all(ok, topology_data_path(traj_path)//': cannot write the trajectory''s topology (&output '// &
                       'trajectory_file): '//trim(msg))
    end subroutine create_topology_data

    !> A restart continues the outputs of the interrupted run (the deck's files, or the parts that
    !> run wrote, its checkpoint's output_part): the thermo CSV and the trajectory keep what was
    !> written up to the checkpoint (anything later is dropped) and are appended to. With &system
    !> restart_outputs = 'new' it writes the next free part instead (<stem>.partN<ext>, N from 2,
    !> past the checkpoint's part and any existing file) and leaves the earlier files as they are:
    !> for a trajectory that a kill inside an HDF5 flush left unreadable, or a lost one.
    subroutine open_outputs_append(extra_header, end_time)
        character(len=*), intent(in) :: extra_header
        real(dp), intent(in) :: end_time
        integer(i8) :: lines, frames, part
        character(len=:), allocatable :: traj_path, thermo_path
        character(len=*), parameter :: hint = " (to go on in new files and leave this one as it is: &system "// &
                                             "restart_outputs = 'new')"
        ok = .true.
        lines = eng%restart_values%get_i('thermo_lines', ok)
        frames = eng%restart_values%get_i('trajectory_frames', ok)
        part = 1
        if (eng%restart_values%has('output_part')) part = eng%restart_values%get_i('output_part', ok)
        call check_all(ok .and. part >= 1, trim(cfg%read_checkpoint)//': &system: read_checkpoint: damaged '// &
                       'checkpoint (output counters)')
        if (cfg%restart_outputs == 'new') then
            part = next_free_part(part + 1)
            ctl%output_part = part
            call create_outputs(part_path(trim(cfg%trajectory_file), part), part_path(trim(cfg%thermo_file), part), &
                                extra_header, end_time)
            if (world%rank == 0 .and. len_trim(cfg%trajectory_file) + len_trim(cfg%thermo_file) > 0) &
                write (output_unit, '(a)') "restart_outputs = 'new': the run goes on in "// &
                    trim(list_parts())//'; the earlier files are left as they are'
            return
        end if
        ctl%output_part = part
        traj_path = part_path(trim(cfg%trajectory_file), part)
        thermo_path = part_path(trim(cfg%thermo_file), part)
        ! every output is checked before any is cut back: a restart that fails changes nothing
        call thermo%check_append(thermo_path, lines, ok, msg)
        call any_failed(ok)
        call check_all(ok, thermo_path//': cannot continue the thermo file (&output thermo_file) from the '// &
                       'checkpoint: '//trim(msg)//hint)
        call traj%open_append(traj_path, world%comm, frames, ok, msg)
        call check_all(ok, traj_path//': cannot continue the trajectory (&output trajectory_file) from the '// &
                       'checkpoint: '//trim(msg)//hint)
        if (allocated(eng%mesh_tet)) then
            call traj%add_mesh(eng%mesh_tet, eng%natoms, ok, msg)
            call check_all(ok, traj_path//': cannot continue the trajectory (&output trajectory_file) from the '// &
                           'checkpoint: '//trim(msg))
        end if
        call thermo%open_append(thermo_path, end_time, trim(cfg%units%time), extra_header, lines, ok, msg, &
                                 units=cfg%units, mesh=allocated(eng%mesh_tet))
        call any_failed(ok)
        call check_all(ok, thermo_path//': cannot continue the thermo file (&output thermo_file) from the '// &
                       'checkpoint: '//trim(msg)//hint)
    end subroutine open_outputs_append

    !> The first part from n on whose thermo CSV and trajectory both do not exist (rank 0 looks).
    integer(i8) function next_free_part(n) result(k)
        integer(i8), intent(in) :: n
        logical :: taken, t2
        k = 0
        if (world%rank == 0) then
            k = n
            do
                taken = .false.; t2 = .false.
                if (len_trim(cfg%trajectory_file) > 0) inquire (file=part_path(trim(cfg%trajectory_file), k), &
                                                               exist=taken)
                if (len_trim(cfg%thermo_file) > 0) inquire (file=part_path(trim(cfg%thermo_file), k), exist=t2)
                if (.not. (taken .or. t2)) exit
                k = k + 1
            end do
        end if
        call sum_all_i8(k)
    end function next_free_part

    !> The part files this run writes, for the screen ("thermo.part2.csv and traj.part2.h5").
    function list_parts() result(t)
        character(len=:), allocatable :: t
        t = ''
        if (len_trim(cfg%thermo_file) > 0) t = part_path(trim(cfg%thermo_file), ctl%output_part)
        if (len_trim(cfg%trajectory_file) > 0) then
            if (len(t) > 0) t = t//' and '
            t = t//part_path(trim(cfg%trajectory_file), ctl%output_part)
        end if
    end function list_parts

    !> ok becomes .false. on every rank when it is .false. on any (outputs are opened by rank 0).
    subroutine any_failed(ok)
        logical, intent(inout) :: ok
        logical :: failed
        failed = .not. ok
        call any_all(failed)
        ok = .not. failed
    end subroutine any_failed

    subroutine print_help()
        write (output_unit, '(a)') 'terrace '//terrace_version_string//': molecular dynamics with energy stepping', &
            '', &
            'usage: [mpirun -np N] terrace [--check] RUN.nml', &
            '       terrace --version | --help', &
            '', &
            '  RUN.nml    Fortran namelist input: groups &run, &system, &potential, &integrator,', &
            '             &thermostat, &neighbor, &output (keys, units and defaults: doc/input.md)', &
            '  --check    read and validate the input, build the system, print the scene plan', &
            '             (what will be computed and what is skipped), run nothing, write nothing', &
            '  --version  print the version', &
            '', &
            'Exit status: 0 success, 1 error in the input or the run, 2 bad command line,', &
            '             3 stopped early with a checkpoint (&run walltime_limit, SIGTERM or SIGUSR1):', &
            '             resubmit with &system read_checkpoint (doc/checkpoints.md)'
    end subroutine print_help

end program terrace
