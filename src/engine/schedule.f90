!> The run's schedule (worked out once from the deck by terrace_run_schedule): when the run ends, when
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
    implicit none
    private

    type, public :: schedule_t
        integer(i8) :: n_steps = 0            !< Verlet: steps; energy stepping: most events (huge: none)
        real(dp) :: t_end = huge(1.0_dp)      !< energy stepping: end time (huge: none)
        integer(i8) :: thermo_every = 0       !< samples every N steps / events (0: by time)
        real(dp) :: thermo_interval = 0       !< energy stepping: samples at multiples of this (0: by count)
        integer(i8) :: traj_every = 0         !< frames every N steps / events (0: by time or none)
        real(dp) :: traj_interval = 0         !< energy stepping: frames at multiples of this (0: by count)
        real(dp) :: covered = 0               !< the time the outputs cover (0: unknown)
    contains
        procedure :: sample_due => schedule_sample_due
        procedure :: frame_due => schedule_frame_due
        procedure :: end_time => schedule_end_time
    end type schedule_t

contains

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
    pure real(dp) function schedule_end_time(self) result(t)
        class(schedule_t), intent(in) :: self
        t = self%covered
    end function schedule_end_time

end module terrace_schedule
