!> Velocity Verlet, the reference integrator:
!>   v += dt/2 F/m;  x += dt v;  [rebuild or refresh ghosts];  F = F(x);  v += dt/2 F/m
!> Energies and the virial are computed only on the steps that are sampled.
!> A thermostat (terrace_thermostat) acts through its hooks: pre_kick before the first half kick,
!> kick_drift in place of the first half kick and the drift where the style replaces them
!> (Langevin's BAOAB), post_kick after the second half kick, then hold_momentum (zero_momentum).
!> Thermo gains ecouple and econserve = etotal - ecouple (with a barostat + P0 V + the barostat's own
!> energy), and the drift report is that of econserve.
!> Checkpoints are taken at the end of a step whose positions were just used for a neighbour-list
!> build (forced at checkpoint_every steps), so that a restart rebuilds the same list
!> (terrace_run_control); a restart continues with the step after the checkpoint's.
module terrace_velocity_verlet
    use terrace_kinds, only: dp, i8
    use terrace_vec3, only: add_scaled
    use terrace_engine, only: engine_t, list_rebuild, list_prune
    use terrace_schedule, only: schedule_t
    use terrace_observables, only: thermo_sample_t
    use terrace_scene_plan, only: pair_all
    use terrace_timers, only: t_output
    use terrace_errors, only: check_all
    use terrace_named_values, only: named_values_t
    use terrace_calendar, only: calendar_t, cal_sample, cal_frame, cal_checkpoint
    use terrace_run_parts, only: run_parts_t
    implicit none
    private

    !> What velocity Verlet is made from (the run's units applied).
    type, public :: verlet_params_t
        real(dp) :: dt = 0
        character(len=:), allocatable :: restart_from   !< the checkpoint a restart read (for messages)
    end type verlet_params_t

    !> One end of the run for the drift report: a thermo sample and the barostat's terms of the
    !> conserved quantity at it (P0 V and the barostat's own energy; 0 without one).
    type :: drift_end_t
        type(thermo_sample_t) :: s
        real(dp) :: baro = 0
    end type drift_end_t

    !> One Verlet run: its parts, its parameters, its calendar (samples, frames, checkpoints, counted
    !> in steps) and the two ends of the drift report.
    type, extends(run_parts_t) :: vv_run_t
        type(verlet_params_t) :: p
        type(calendar_t) :: cal
        type(drift_end_t) :: first, last
    contains
        procedure :: exchange_own => exchange_first
    end type vv_run_t

    public :: run_velocity_verlet

contains

    subroutine run_velocity_verlet(parts, p, sched)
        type(run_parts_t), intent(in) :: parts
        type(verlet_params_t), intent(in) :: p
        type(schedule_t), intent(in) :: sched
        type(vv_run_t) :: r
        integer(i8) :: step, step0
        real(dp) :: dt, dtfm(size(parts%eng%atoms%mass)), dtf
        logical :: sample, frame, scheduled, safe, stop_now, moved
        r%run_parts_t = parts; r%p = p
        associate (eng => r%eng, ts => r%ts, bs => r%bs, out => r%out, cal => r%cal, last => r%last)
            dt = p%dt
            dtf = 0.5_dp*dt*eng%units%ftm2v
            dtfm = dtf/eng%atoms%mass
            cal%every(cal_sample) = sched%thermo_every
            cal%every(cal_frame) = sched%traj_every
            cal%every(cal_checkpoint) = out%ctl%every
            step0 = 0
            if (eng%restarted) then
                call restore_state(r, step0)
            else
                call eng%timers%start(t_output)
                r%first%s = eng%sample(0_i8, 0.0_dp)
                if (ts%active()) r%first%s%ecouple = ts%ecouple()
                r%first%baro = baro_terms()
                call write_sample(r%first%s)
                if (cal%count_due(cal_frame, 0_i8)) call out%frame(eng, 0_i8, 0.0_dp, r%first%s)
                call eng%timers%stop(t_output)
            end if
            last = r%first
            do step = step0 + 1, sched%n_steps
                call bs%follow(eng%units%boltz*ts%target((step - 0.5_dp)*dt))   ! the thermostat's target (a ramp)
                call ts%pre_kick(eng%atoms, dt, step, (step - 0.5_dp)*dt)
                if (ts%traits%replaces_kick_drift) then
                    call ts%kick_drift(eng%atoms, dtfm, dt, step, (step - 0.5_dp)*dt)
                else if (bs%replaces_kicks()) then
                    call bs%first_half(eng, dtfm, dtf, dt, step)
                else
                    call kick(eng, dtfm, dtf, dt, .true.)
                end if
                scheduled = cal%count_due(cal_checkpoint, step)
                call bs%before_forces(eng, step, moved)
                if (moved) then
                    safe = .true.                 ! the box changed: the list was just rebuilt here
                else
                    safe = move_ghosts(eng, step, scheduled)
                end if
                sample = cal%count_due(cal_sample, step) .or. step == sched%n_steps
                frame = cal%count_due(cal_frame, step)
                call eng%compute_forces(sample .or. frame .or. bs%needs_virial(step))
                if (eng%validity_checks) call eng%check_valid(step, step*dt)
                if (bs%replaces_kicks()) then
                    call bs%second_half(eng, dtfm, dtf, dt, step)
                else
                    call kick(eng, dtfm, dtf, dt, .false.)
                end if
                call ts%post_kick(eng%atoms, dt, step, (step - 0.5_dp)*dt)
                call ts%hold_momentum(eng%atoms)
                call bs%after_step(eng, step, moved)
                safe = safe .or. moved
                if (sample) then
                    call eng%timers%start(t_output)
                    last%s = eng%sample(step, step*dt)
                    if (ts%active()) last%s%ecouple = ts%ecouple()
                    last%baro = baro_terms()
                    call write_sample(last%s)
                    call eng%timers%stop(t_output)
                end if
                if (frame) call out%frame(eng, step, step*dt, eng%sample(step, step*dt))
                call out%thermo%tick(step, step*dt)
                ! ecouple's per-rank parts are folded at every safe point, so that a run continued from a
                ! checkpoint (always taken at one) sums them exactly as the uninterrupted run does
                if (safe .and. ts%active()) call ts%fold()
                if (safe .and. out%ctl%active) then
                    stop_now = out%ctl%stop_requested()
                    if (stop_now .or. scheduled) call r%checkpoint(step, step*dt, scheduled)
                    if (out%ctl%stopped) exit
                end if
            end do
            if (.not. out%ctl%stopped) call report_drift(r%first, last, eng%natoms, ts%active(), bs%active(), eng%units)
        end associate

    contains

        !> A thermo line; with a barostat the columns vol, box_lx, box_ly, box_lz, and P0 V in the conserved
        !> quantity (econserve = etotal + P0 V - ecouple).
        subroutine write_sample(s)
            type(thermo_sample_t), intent(in) :: s
            if (r%bs%active()) then
                call r%out%sample(s, s%etotal + baro_terms(), [r%eng%box%volume(), r%eng%box%length])
            else
                call r%out%sample(s, s%etotal)
            end if
        end subroutine write_sample

        !> The barostat's terms of the conserved quantity: P0 V and its own energy (0 without one).
        real(dp) function baro_terms()
            baro_terms = 0
            if (r%bs%active()) baro_terms = r%bs%pv(r%eng) + r%bs%energy(r%eng)
        end function baro_terms
    end subroutine run_velocity_verlet

    !> The first half kick and the drift (drift), or the second half kick, of the owned atoms.
    subroutine kick(eng, dtfm, dtf, dt, drift)
        type(engine_t), intent(inout) :: eng
        real(dp), intent(in) :: dtfm(:), dtf, dt
        logical, intent(in) :: drift
        if (eng%atoms%per_atom_mass) then
            call kick_masses(eng%atoms%nlocal, eng%atoms%x, eng%atoms%v, eng%atoms%f, eng%atoms%rmass, dtf, dt, drift)
        else
            call kick_types(eng%atoms%nlocal, eng%atoms%x, eng%atoms%v, eng%atoms%f, eng%atoms%type, dtfm, dt, drift)
        end if
    end subroutine kick

    !> After the drift: the neighbour list rebuilt when due (or the ghosts refreshed, and with
    !> &neighbor outer_skin the force pass's list pruned again when due: engine_list_due). Returns
    !> whether this step is a safe point (a list build; on the all-pairs path a scheduled checkpoint
    !> or every poll_all_pairs steps).
    logical function move_ghosts(eng, step, scheduled) result(safe)
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: step
        logical, intent(in) :: scheduled
        integer(i8), parameter :: poll_all_pairs = 10   !< all-pairs path: steps between stop polls
        integer :: due
        if (eng%plan%pair_mode /= pair_all) then
            due = eng%list_due(step, scheduled)
            safe = due == list_rebuild
            if (safe) then
                call eng%rebuild()
            else
                call eng%refresh_ghosts()
                if (due == list_prune) call eng%prune()       ! (&neighbor outer_skin: from the ghosts' new places)
            end if
        else
            call eng%refresh_ghosts()
            safe = scheduled .or. mod(step, poll_all_pairs) == 0
        end if
    end function move_ghosts

    !> A restart: the step the checkpoint was taken at, and the run's own keys read (exchange_first).
    !> (The energy guard takes its reference at the first sample after the restart.)
    subroutine restore_state(r, step0)
        type(vv_run_t), intent(inout) :: r
        integer(i8), intent(out) :: step0
        logical :: ok
        ok = .true.
        step0 = r%eng%restart_values%get_i('step', ok)
        r%first%s%step = 0; r%first%s%time = 0
        call r%exchange_own(r%eng%restart_values, .false., ok)
        call r%restore_coupling(r%eng%restart_values, ok)
        call check_all(ok, r%p%restart_from//': &system: read_checkpoint: damaged checkpoint '// &
                       '(velocity Verlet state missing)')
    end subroutine restore_state

    !> The Verlet run's own restart keys, in one place: the first sample's energy and momentum (the
    !> drift report of a continued run), with a thermostat its ecouple, with a barostat its first
    !> terms of the conserved quantity (first%baro); written to (saving) or read from a
    !> checkpoint's values. (The thermostat's and the barostat's own state: run_parts_t.)
    subroutine exchange_first(self, values, saving, ok)
        class(vv_run_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        character(len=12), parameter :: keys(4) = [character(len=12) :: 'first_etotal', 'first_px', 'first_py', &
                                                                          'first_pz']
        real(dp) :: vals(4)
        integer :: k
        associate (first => self%first, ts => self%ts, bs => self%bs)
            if (saving) then
                vals = [first%s%etotal, first%s%momentum]
                do k = 1, 4
                    call values%put(trim(keys(k)), vals(k))
                end do
                if (ts%active()) call values%put('first_ecouple', first%s%ecouple)
                if (bs%active()) call values%put('first_baro', first%baro)
                return
            end if
            do k = 1, 4
                vals(k) = values%get_r(trim(keys(k)), ok)
            end do
            first%s%etotal = vals(1); first%s%momentum = vals(2:4)
            if (ts%active()) first%s%ecouple = values%get_r('first_ecouple', ok)
            if (bs%active()) first%baro = values%get_r('first_baro', ok)
        end associate
    end subroutine exchange_first

    !> Half kick v += dtfm(type) f of the n owned atoms and, when drift, the drift x += dt v.
    !> Explicit shapes: the compiler sees contiguous, unaliased columns and vectorises (through the
    !> engine's components it kept the loops scalar: 5 % of an in.lj step).
    subroutine kick_types(n, x, v, f, type, dtfm, dt, drift)
        integer, intent(in) :: n, type(n)
        real(dp), intent(inout) :: x(3, n), v(3, n)
        real(dp), intent(in) :: f(3, n), dtfm(:), dt
        logical, intent(in) :: drift
        integer :: i
        if (size(dtfm) == 1) then     ! one type: flat loops over 3n values (the same bits)
            call add_scaled(3*n, dtfm(1), f, v)
            if (drift) call add_scaled(3*n, dt, v, x)
            return
        end if
        if (drift) then
            do i = 1, n
                v(:, i) = v(:, i) + dtfm(type(i))*f(:, i)
                x(:, i) = x(:, i) + dt*v(:, i)
            end do
        else
            do i = 1, n
                v(:, i) = v(:, i) + dtfm(type(i))*f(:, i)
            end do
        end if
    end subroutine kick_types

    !> kick_types with per-atom masses: v += (dtf/rmass) f.
    subroutine kick_masses(n, x, v, f, rmass, dtf, dt, drift)
        integer, intent(in) :: n
        real(dp), intent(inout) :: x(3, n), v(3, n)
        real(dp), intent(in) :: f(3, n), rmass(n), dtf, dt
        logical, intent(in) :: drift
        integer :: i
        if (drift) then
            do i = 1, n
                v(:, i) = v(:, i) + (dtf/rmass(i))*f(:, i)
                x(:, i) = x(:, i) + dt*v(:, i)
            end do
        else
            do i = 1, n
                v(:, i) = v(:, i) + (dtf/rmass(i))*f(:, i)
            end do
        end if
    end subroutine kick_masses

    !> Energy drift per atom per time unit (of econserve = etotal - ecouple with a thermostat, plus
    !> P0 V and the barostat's own energy with a barostat: first%baro, last%baro) and the change of
    !> total momentum over the run, in the deck's units.
    subroutine report_drift(first, last, natoms, thermostat, barostat, units)
        use terrace_mpi_env, only: world
        use terrace_units, only: units_t
        use, intrinsic :: iso_fortran_env, only: output_unit
        type(drift_end_t), intent(in) :: first, last
        integer(i8), intent(in) :: natoms
        logical, intent(in) :: thermostat, barostat
        type(units_t), intent(in) :: units
        real(dp) :: drift
        character(len=:), allocatable :: per_atom
        if (world%rank /= 0 .or. last%s%time <= first%s%time) return
        drift = ((last%s%etotal + last%baro - last%s%ecouple) - (first%s%etotal + first%baro - first%s%ecouple))/ &
                (real(natoms, dp)*(last%s%time - first%s%time))
        call summary_drift(first%s, last%s, natoms, thermostat, drift)
        if (barostat) call summary_put_baro(last%baro - first%baro)
        per_atom = ' '//trim(units%energy)//' per atom per '//trim(units%time)
        if (thermostat) then
            write (output_unit, '(a,es12.4,a,es12.4,a)') 'Energy drift (econserve): ', drift, &
                per_atom//';  energy put in by the thermostat: ', last%s%ecouple - first%s%ecouple, ' '//trim(units%energy)
            return
        end if
        write (output_unit, '(a,es12.4,a,es12.4,a)') 'Energy drift: ', drift, &
            per_atom//';  |P_end - P_0| = ', norm2(last%s%momentum - first%s%momentum), &
            ' '//trim(units%mass)//' '//trim(units%velocity)
    end subroutine report_drift

    !> report_drift's figures in the run summary.
    subroutine summary_drift(first, last, natoms, thermostat, drift)
        use terrace_run_summary, only: summary_put
        type(thermo_sample_t), intent(in) :: first, last
        integer(i8), intent(in) :: natoms
        logical, intent(in) :: thermostat
        real(dp), intent(in) :: drift
        call summary_put('conservation/energy_drift_per_atom_time', drift)
        call summary_put('conservation/energy_drift_of', trim(merge('econserve', 'etotal   ', thermostat)))
        call summary_put('conservation/momentum_change', norm2(last%momentum - first%momentum))
        if (thermostat) call summary_put('conservation/thermostat_energy', last%ecouple - first%ecouple)
    end subroutine summary_drift

    !> The change of the barostat's terms of econserve (P0 V and its own energy) in the run summary.
    subroutine summary_put_baro(change)
        use terrace_run_summary, only: summary_put
        real(dp), intent(in) :: change
        call summary_put('conservation/barostat_energy', change)
    end subroutine summary_put_baro

end module terrace_velocity_verlet
