!> The run's schedule, worked out once from the deck for both integrators: when the run ends, when
!> thermo samples and trajectory frames are due, in steps (velocity Verlet) or in events or times
!> (energy stepping, which ends a window exactly at the next due time).
!>   Verlet: n_steps from &run n_steps or run_time/dt; samples every thermo_every steps (or
!>           thermo_interval/dt; default a tenth of the run); frames every trajectory_every steps (or
!>           trajectory_interval/dt; default the thermo sampling).
!>   Energy stepping: ends at run_time or after n_steps events; samples every thermo_every events
!>           or at multiples of thermo_interval (default a tenth of run_time); frames likewise.
!> Checkpoint times and steps are run_control's (they depend on what was already written).
module terrace_schedule
    use terrace_kinds, only: dp, i8
    use terrace_config, only: config_t
    implicit none
    private

    type, public :: schedule_t
        integer(i8) :: n_steps = 0            !< Verlet: steps; energy stepping: most events (huge: none)
        real(dp) :: t_end = huge(1.0_dp)      !< energy stepping: end time (huge: none)
        integer(i8) :: thermo_every = 0       !< samples every N steps / events (0: by time)
        real(dp) :: thermo_interval = 0       !< energy stepping: samples at multiples of this (0: by count)
        integer(i8) :: traj_every = 0         !< frames every N steps / events (0: by time or none)
        real(dp) :: traj_interval = 0         !< energy stepping: frames at multiples of this (0: by count)
    contains
        procedure :: sample_due => schedule_sample_due
        procedure :: frame_due => schedule_frame_due
        procedure :: end_time => schedule_end_time
    end type schedule_t

    public :: make_schedule

contains

    !> The schedule of the deck's integrator.
    function make_schedule(cfg) result(s)
        type(config_t), intent(in) :: cfg
        type(schedule_t) :: s
        if (cfg%integrator == 'energy_stepping') then
            if (cfg%run_time > 0) s%t_end = cfg%run_time
            s%n_steps = huge(1_i8)
            if (cfg%n_steps >= 0) s%n_steps = cfg%n_steps
            if (cfg%thermo_every > 0) then
                s%thermo_every = cfg%thermo_every
            else if (cfg%thermo_interval > 0) then
                s%thermo_interval = cfg%thermo_interval
            else if (cfg%run_time > 0) then
                s%thermo_interval = cfg%run_time/10
            else
                s%thermo_every = max(1_i8, s%n_steps/10)
            end if
            s%traj_every = max(0_i8, cfg%trajectory_every)
            s%traj_interval = max(0.0_dp, cfg%trajectory_interval)
            if (s%traj_every == 0 .and. .not. s%traj_interval > 0) then
                s%traj_every = s%thermo_every; s%traj_interval = s%thermo_interval
            end if
        else
            s%n_steps = cfg%n_steps
            if (s%n_steps < 0) s%n_steps = max(1_i8, nint(cfg%run_time/cfg%dt, i8))
            if (cfg%thermo_every > 0) then
                s%thermo_every = cfg%thermo_every
            else if (cfg%thermo_interval > 0) then
                s%thermo_every = max(1_i8, nint(cfg%thermo_interval/cfg%dt, i8))
            else
                s%thermo_every = max(1_i8, s%n_steps/10)
            end if
            s%traj_every = 0
            if (cfg%trajectory_every > 0) s%traj_every = cfg%trajectory_every
            if (cfg%trajectory_interval > 0) s%traj_every = max(1_i8, nint(cfg%trajectory_interval/cfg%dt, i8))
            if (cfg%trajectory_every <= 0 .and. .not. cfg%trajectory_interval > 0) s%traj_every = s%thermo_every
        end if
        if (len_trim(cfg%trajectory_file) == 0) then
            s%traj_every = 0; s%traj_interval = 0
        end if
    end function make_schedule

    !> A sample by count is due after step / event n (the last step of a Verlet run always is).
    pure logical function schedule_sample_due(self, n) result(due)
        class(schedule_t), intent(in) :: self
        integer(i8), intent(in) :: n
        due = every(self%thermo_every, n)
    end function schedule_sample_due

    pure logical function schedule_frame_due(self, n) result(due)
        class(schedule_t), intent(in) :: self
        integer(i8), intent(in) :: n
        due = every(self%traj_every, n)
    end function schedule_frame_due

    !> n is a multiple of k (never, when k is 0).
    pure logical function every(k, n)
        integer(i8), intent(in) :: k, n
        every = .false.
        if (k > 0) every = mod(n, k) == 0
    end function every

    !> The time the outputs cover: n_steps dt for Verlet, run_time for energy stepping (0: unknown).
    pure real(dp) function schedule_end_time(self, cfg) result(t)
        class(schedule_t), intent(in) :: self
        type(config_t), intent(in) :: cfg
        if (cfg%integrator == 'energy_stepping') then
            t = merge(self%t_end, 0.0_dp, cfg%run_time > 0)
        else
            t = self%n_steps*cfg%dt
        end if
    end function schedule_end_time

end module terrace_schedule
