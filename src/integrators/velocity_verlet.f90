!> Velocity Verlet (NVE), the reference integrator:
!>   v += dt/2 F/m;  x += dt v;  [rebuild or refresh ghosts];  F = F(x);  v += dt/2 F/m
!> Energies and the virial are computed only on the steps that are sampled.
module terrace_velocity_verlet
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_thermo, only: thermo_writer_t, thermo_sample_t
    use terrace_trajectory, only: trajectory_t
    use terrace_scene_plan, only: pair_cells
    use terrace_timers, only: t_output
    use terrace_errors, only: check_all
    use terrace_run_checks, only: energy_guard_t
    implicit none
    private

    public :: run_velocity_verlet

contains

    subroutine run_velocity_verlet(eng, thermo, traj, n_steps, thermo_every, traj_every)
        type(engine_t), intent(inout) :: eng
        type(thermo_writer_t), intent(inout) :: thermo
        type(trajectory_t), intent(inout) :: traj
        integer(i8), intent(in) :: n_steps, thermo_every, traj_every
        integer(i8) :: step
        integer :: i, t
        real(dp) :: dt, dtfm(size(eng%atoms%mass))
        logical :: sample, frame
        type(thermo_sample_t) :: first, last
        type(energy_guard_t) :: guard
        dt = eng%cfg%dt
        do t = 1, size(dtfm)
            dtfm(t) = 0.5_dp*dt*eng%cfg%units%ftm2v/eng%atoms%mass(t)
        end do
        call eng%timers%start(t_output)
        first = eng%sample(0_i8, 0.0_dp)
        call guard%check(first)
        call thermo%write(first)
        call write_frame(0_i8, first)
        last = first
        call eng%timers%stop(t_output)
        do step = 1, n_steps
            do i = 1, eng%atoms%nlocal
                eng%atoms%v(:, i) = eng%atoms%v(:, i) + dtfm(eng%atoms%type(i))*eng%atoms%f(:, i)
                eng%atoms%x(:, i) = eng%atoms%x(:, i) + dt*eng%atoms%v(:, i)
            end do
            if (eng%plan%pair_mode == pair_cells) then
                if (eng%list%needs_rebuild(eng%atoms)) then
                    call eng%rebuild()
                else
                    call eng%refresh_ghosts()
                end if
            else
                call eng%refresh_ghosts()
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
        end do
        call report_drift(first, last, eng%natoms)

    contains

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
