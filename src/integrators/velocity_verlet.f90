!> Velocity Verlet, the reference integrator:
!>   v += dt/2 F/m;  x += dt v;  [rebuild or refresh ghosts];  F = F(x);  v += dt/2 F/m
!> Energies and the virial are computed only on the steps that are sampled.
!> With a thermostat (terrace_thermostat): Langevin replaces the drift by BAOAB's A O A (the
!> exact Ornstein-Uhlenbeck step between two half drifts); CSVR and Nose-Hoover chains act for
!> dt/2 before the first and after the second half kick; Andersen collisions follow the step;
!> zero_momentum then removes the total momentum. Thermo gains ecouple and econserve = etotal -
!> ecouple, and the drift report is that of econserve.
!> Checkpoints are taken at the end of a step whose positions were just used for a neighbour-list
!> build (forced at checkpoint_every steps), so that a restart rebuilds the same list
!> (terrace_run_control); a restart continues with the step after the checkpoint's.
module terrace_velocity_verlet
    use terrace_kinds, only: dp, i8
    use terrace_vec3, only: add_scaled
    use terrace_engine, only: engine_t
    use terrace_schedule, only: schedule_t
    use terrace_thermo, only: thermo_writer_t
    use terrace_observables, only: thermo_sample_t
    use terrace_trajectory, only: trajectory_t
    use terrace_scene_plan, only: pair_all
    use terrace_timers, only: t_output
    use terrace_errors, only: check_all
    use terrace_run_control, only: run_control_t
    use terrace_checkpoint, only: ckpt_values_t
    use terrace_run_checks, only: energy_guard_t
    use terrace_thermostat, only: thermostat_t, thermostat_langevin, thermostat_csvr, thermostat_nose_hoover, &
                                  thermostat_andersen
    implicit none
    private

    public :: run_velocity_verlet

contains

    subroutine run_velocity_verlet(eng, thermo, traj, sched, ctl)
        type(engine_t), intent(inout) :: eng
        type(thermo_writer_t), intent(inout) :: thermo
        type(trajectory_t), intent(inout) :: traj
        type(schedule_t), intent(in) :: sched
        type(run_control_t), intent(inout) :: ctl
        integer(i8), parameter :: poll_all_pairs = 10   !< all-pairs path: steps between stop polls
        integer(i8) :: step, step0
        integer :: t
        real(dp) :: dt, dtfm(size(eng%atoms%mass)), dtf
        logical :: sample, frame, scheduled, safe, ok, stop_now
        type(thermo_sample_t) :: first, last
        type(energy_guard_t) :: guard
        type(thermostat_t) :: ts
        real(dp) :: t_mid
        dt = eng%cfg%dt
        call ts%configure(eng%cfg, eng%natoms, sched%n_steps*dt)
        dtf = 0.5_dp*dt*eng%cfg%units%ftm2v
        do t = 1, size(dtfm)
            dtfm(t) = 0.5_dp*dt*eng%cfg%units%ftm2v/eng%atoms%mass(t)
        end do
        step0 = 0
        if (eng%restarted) then
            ! the first sample of the whole run (for the drift report) and the step reached
            ok = .true.
            step0 = eng%restart_values%get_i('step', ok)
            first%step = 0; first%time = 0
            first%etotal = eng%restart_values%get_r('first_etotal', ok)
            first%momentum(1) = eng%restart_values%get_r('first_px', ok)
            first%momentum(2) = eng%restart_values%get_r('first_py', ok)
            first%momentum(3) = eng%restart_values%get_r('first_pz', ok)
            if (ts%active()) then
                first%ecouple = eng%restart_values%get_r('first_ecouple', ok)
                call ts%restore(eng%restart_values, ok)
            end if
            call check_all(ok, trim(eng%cfg%read_checkpoint)//': &system: read_checkpoint: damaged checkpoint '// &
                           '(velocity Verlet state missing)')
            ! (the energy guard takes its reference at the first sample after the restart)
        else
            call eng%timers%start(t_output)
            first = eng%sample(0_i8, 0.0_dp)
            if (ts%active()) first%ecouple = ts%ecouple()
            call guard%check(first)
            call write_thermo(first)
            call write_frame(0_i8, first)
            call eng%timers%stop(t_output)
        end if
        last = first
        do step = step0 + 1, sched%n_steps
            t_mid = (step - 0.5_dp)*dt
            select case (ts%style)
            case (thermostat_csvr)
                call ts%csvr(eng%atoms, 0.5_dp*dt, 2*step, t_mid)
            case (thermostat_nose_hoover)
                call ts%nose_hoover(eng%atoms, 0.5_dp*dt, t_mid)
            end select
            if (ts%style == thermostat_langevin) then
                call ts%langevin_kick_drift(eng%atoms, dtfm, dt, step, t_mid)
            else if (eng%atoms%per_atom_mass) then
                call kick_masses(eng%atoms%nlocal, eng%atoms%x, eng%atoms%v, eng%atoms%f, eng%atoms%rmass, dtf, dt, .true.)
            else
                call kick_types(eng%atoms%nlocal, eng%atoms%x, eng%atoms%v, eng%atoms%f, eng%atoms%type, dtfm, dt, .true.)
            end if
            scheduled = .false.
            if (ctl%every > 0) scheduled = mod(step, ctl%every) == 0
            if (eng%plan%pair_mode /= pair_all) then
                safe = eng%list%rebuild_due(eng%atoms, step, scheduled)
                if (safe) then
                    call eng%rebuild()
                else
                    call eng%refresh_ghosts()
                end if
            else
                call eng%refresh_ghosts()
                safe = scheduled .or. mod(step, poll_all_pairs) == 0
            end if
            sample = sched%sample_due(step) .or. step == sched%n_steps
            frame = sched%frame_due(step)
            call eng%compute_forces(sample .or. frame)
            if (eng%validity_checks) call eng%check_valid(step, step*dt)
            if (eng%atoms%per_atom_mass) then
                call kick_masses(eng%atoms%nlocal, eng%atoms%x, eng%atoms%v, eng%atoms%f, eng%atoms%rmass, dtf, dt, .false.)
            else
                call kick_types(eng%atoms%nlocal, eng%atoms%x, eng%atoms%v, eng%atoms%f, eng%atoms%type, dtfm, dt, .false.)
            end if
            select case (ts%style)
            case (thermostat_csvr)
                call ts%csvr(eng%atoms, 0.5_dp*dt, 2*step + 1, t_mid)
            case (thermostat_nose_hoover)
                call ts%nose_hoover(eng%atoms, 0.5_dp*dt, t_mid)
            case (thermostat_andersen)
                call ts%andersen_step(eng%atoms, dt, step, step*dt)
            end select
            if (ts%zero_momentum) call ts%remove_momentum(eng%atoms)
            if (sample) then
                call eng%timers%start(t_output)
                last = eng%sample(step, step*dt)
                if (ts%active()) last%ecouple = ts%ecouple()
                call guard%check(last)
                call write_thermo(last)
                call eng%timers%stop(t_output)
            end if
            if (frame) call write_frame(step, eng%sample(step, step*dt))
            ! ecouple's per-rank parts are folded at every safe point, so that a run continued from a
            ! checkpoint (always taken at one) sums them exactly as the uninterrupted run does
            if (safe .and. ts%active()) call ts%fold()
            if (safe .and. ctl%active) then
                stop_now = ctl%stop_requested()
                if (stop_now .or. scheduled) call checkpoint(step, scheduled)
                if (ctl%stopped) exit
            end if
        end do
        if (.not. ctl%stopped) call report_drift(first, last, eng%natoms, ts%active())

    contains

        !> A thermo line; with a thermostat ecouple (set by the caller) and econserve too.
        subroutine write_thermo(s)
            type(thermo_sample_t), intent(inout) :: s
            if (ts%active()) then
                call thermo%write(s, [s%ecouple, s%etotal - s%ecouple])
            else
                call thermo%write(s)
            end if
        end subroutine write_thermo

        subroutine checkpoint(step, scheduled)
            integer(i8), intent(in) :: step
            logical, intent(in) :: scheduled
            type(ckpt_values_t) :: values
            logical :: ok
            character(len=512) :: msg
            call eng%timers%start(t_output)
            call values%put('first_etotal', first%etotal)
            call values%put('first_px', first%momentum(1))
            call values%put('first_py', first%momentum(2))
            call values%put('first_pz', first%momentum(3))
            if (ts%active()) then
                call values%put('first_ecouple', first%ecouple)
                call ts%save(values)
            end if
            ! the trajectory holds every frame the checkpoint counts, even if the run is killed next
            call traj%flush(ok, msg)
            call check_all(ok, trim(msg))
            call ctl%write(eng, values, step, step*dt, thermo%lines, traj%frames(), scheduled)
            call eng%timers%stop(t_output)
        end subroutine checkpoint

        subroutine write_frame(step, s)
            integer(i8), intent(in) :: step
            type(thermo_sample_t), intent(in) :: s
            logical :: ok
            character(len=512) :: msg
            if (.not. sched%frame_due(step)) return
            call eng%timers%start(t_output)
            call traj%write(step, step*dt, eng%atoms, s, ok, msg)
            call check_all(ok, trim(msg))
            call eng%timers%stop(t_output)
        end subroutine write_frame

    end subroutine run_velocity_verlet

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

    !> Energy drift per atom per time unit (of econserve = etotal - ecouple with a thermostat) and
    !> the change of total momentum over the run.
    subroutine report_drift(first, last, natoms, thermostat)
        use terrace_mpi_env, only: world
        use, intrinsic :: iso_fortran_env, only: output_unit
        type(thermo_sample_t), intent(in) :: first, last
        integer(i8), intent(in) :: natoms
        logical, intent(in) :: thermostat
        if (world%rank /= 0 .or. last%time <= first%time) return
        call summary_drift(first, last, natoms, thermostat)
        if (thermostat) then
            write (output_unit, '(a,es12.4,a,es12.4,a)') 'Energy drift (econserve): ', &
                ((last%etotal - last%ecouple) - (first%etotal - first%ecouple))/(real(natoms, dp)*(last%time - first%time)), &
                ' energy/atom/time;  energy put in by the thermostat: ', last%ecouple - first%ecouple, ' energy'
            return
        end if
        write (output_unit, '(a,es12.4,a,es12.4,a)') 'Energy drift: ', &
            (last%etotal - first%etotal)/(real(natoms, dp)*(last%time - first%time)), &
            ' energy/atom/time;  |P_end - P_0| = ', norm2(last%momentum - first%momentum), ' (mass*velocity)'
    end subroutine report_drift

    !> report_drift's figures in the run summary.
    subroutine summary_drift(first, last, natoms, thermostat)
        use terrace_run_summary, only: summary_put
        type(thermo_sample_t), intent(in) :: first, last
        integer(i8), intent(in) :: natoms
        logical, intent(in) :: thermostat
        call summary_put('conservation/energy_drift_per_atom_time', ((last%etotal - last%ecouple) - &
                         (first%etotal - first%ecouple))/(real(natoms, dp)*(last%time - first%time)))
        call summary_put('conservation/energy_drift_of', trim(merge('econserve', 'etotal   ', thermostat)))
        call summary_put('conservation/momentum_change', norm2(last%momentum - first%momentum))
        if (thermostat) call summary_put('conservation/thermostat_energy', last%ecouple - first%ecouple)
    end subroutine summary_drift

end module terrace_velocity_verlet
