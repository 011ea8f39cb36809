!> Velocity Verlet (NVE), the reference integrator:
!>   v += dt/2 F/m;  x += dt v;  [rebuild or refresh ghosts];  F = F(x);  v += dt/2 F/m
!> Energies and the virial are computed only on the steps that are sampled.
!> Checkpoints are taken at the end of a step whose positions were just used for a neighbour-list
!> build (forced at checkpoint_every steps), so that a restart rebuilds the same list
!> (terrace_run_control); a restart continues with the step after the checkpoint's.
module terrace_velocity_verlet
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_thermo, only: thermo_writer_t
    use terrace_observables, only: thermo_sample_t
    use terrace_trajectory, only: trajectory_t
    use terrace_scene_plan, only: pair_cells
    use terrace_timers, only: t_output
    use terrace_errors, only: check_all
    use terrace_run_control, only: run_control_t
    use terrace_checkpoint, only: ckpt_values_t
    use terrace_run_checks, only: energy_guard_t
    implicit none
    private

    public :: run_velocity_verlet

contains

    subroutine run_velocity_verlet(eng, thermo, traj, n_steps, thermo_every, traj_every, ctl)
        type(engine_t), intent(inout) :: eng
        type(thermo_writer_t), intent(inout) :: thermo
        type(trajectory_t), intent(inout) :: traj
        integer(i8), intent(in) :: n_steps, thermo_every, traj_every
        type(run_control_t), intent(inout) :: ctl
        integer(i8), parameter :: poll_all_pairs = 10   !< all-pairs path: steps between stop polls
        integer(i8) :: step, step0
        integer :: i, t
        real(dp) :: dt, dtfm(size(eng%atoms%mass))
        logical :: sample, frame, scheduled, safe, ok, stop_now
        type(thermo_sample_t) :: first, last
        type(energy_guard_t) :: guard
        dt = eng%cfg%dt
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
            call check_all(ok, trim(eng%cfg%read_checkpoint)//': &system: read_checkpoint: damaged checkpoint '// &
                           '(velocity Verlet state missing)')
            ! (the energy guard takes its reference at the first sample after the restart)
        else
            call eng%timers%start(t_output)
            first = eng%sample(0_i8, 0.0_dp)
            call guard%check(first)
            call thermo%write(first)
            call write_frame(0_i8, first)
            call eng%timers%stop(t_output)
        end if
        last = first
        do step = step0 + 1, n_steps
            do i = 1, eng%atoms%nlocal
                eng%atoms%v(:, i) = eng%atoms%v(:, i) + dtfm(eng%atoms%type(i))*eng%atoms%f(:, i)
                eng%atoms%x(:, i) = eng%atoms%x(:, i) + dt*eng%atoms%v(:, i)
            end do
            scheduled = .false.
            if (ctl%every > 0) scheduled = mod(step, ctl%every) == 0
            if (eng%plan%pair_mode == pair_cells) then
                safe = scheduled
                if (.not. safe) safe = eng%list%needs_rebuild(eng%atoms)
                if (safe) then
                    call eng%rebuild()
                else
                    call eng%refresh_ghosts()
                end if
            else
                call eng%refresh_ghosts()
                safe = scheduled .or. mod(step, poll_all_pairs) == 0
            end if
            sample = mod(step, thermo_every) == 0 .or. step == n_steps
            frame = .false.
            if (traj_every > 0) frame = mod(step, traj_every) == 0
            call eng%compute_forces(sample .or. frame)
            do i = 1, eng%atoms%nlocal
                eng%atoms%v(:, i) = eng%atoms%v(:, i) + dtfm(eng%atoms%type(i))*eng%atoms%f(:, i)
            end do
            if (sample) then
                call eng%timers%start(t_output)
                last = eng%sample(step, step*dt)
                call guard%check(last)
                call thermo%write(last)
                call eng%timers%stop(t_output)
            end if
            if (frame) call write_frame(step, eng%sample(step, step*dt))
            if (safe .and. ctl%active) then
                stop_now = ctl%stop_requested()
                if (stop_now .or. scheduled) call checkpoint(step, scheduled)
                if (ctl%stopped) exit
            end if
        end do
        if (.not. ctl%stopped) call report_drift(first, last, eng%natoms)

    contains

        subroutine checkpoint(step, scheduled)
            integer(i8), intent(in) :: step
            logical, intent(in) :: scheduled
            type(ckpt_values_t) :: values
            logical :: ok
            character(len=512) :: msg
            call eng%timers%start(t_output)
            call values%put_r('first_etotal', first%etotal)
            call values%put_r('first_px', first%momentum(1))
            call values%put_r('first_py', first%momentum(2))
            call values%put_r('first_pz', first%momentum(3))
            ! the trajectory holds every frame the checkpoint counts, even if the run is killed next
            call traj%flush(ok, msg)
            call check_all(ok, 'trajectory: '//trim(msg))
            call ctl%write(eng, values, step, step*dt, thermo%lines, traj%frames(), scheduled)
            call eng%timers%stop(t_output)
        end subroutine checkpoint

        subroutine write_frame(step, s)
            integer(i8), intent(in) :: step
            type(thermo_sample_t), intent(in) :: s
            logical :: ok
            character(len=512) :: msg
            if (traj_every <= 0) return
            if (mod(step, traj_every) /= 0) return
            call eng%timers%start(t_output)
            call traj%write(step, step*dt, eng%atoms, s, ok, msg)
            call check_all(ok, 'trajectory: '//trim(msg))
            call eng%timers%stop(t_output)
        end subroutine write_frame

    end subroutine run_velocity_verlet

    !> Energy drift per atom per time unit and the change of total momentum over the run.
    subroutine report_drift(first, last, natoms)
        use terrace_mpi_env, only: world
        use, intrinsic :: iso_fortran_env, only: output_unit
        type(thermo_sample_t), intent(in) :: first, last
        integer(i8), intent(in) :: natoms
        if (world%rank /= 0 .or. last%time <= first%time) return
        write (output_unit, '(a,es12.4,a,es12.4,a)') 'Energy drift: ', &
            (last%etotal - first%etotal)/(real(natoms, dp)*(last%time - first%time)), &
            ' energy/atom/time;  |P_end - P_0| = ', norm2(last%momentum - first%momentum), ' (mass*velocity)'
    end subroutine report_drift

end module terrace_velocity_verlet
