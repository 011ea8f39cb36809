!> Per-phase wall-clock timers (pair, neighbour, communication, output, event search, other).
!> They count ticks of a cheap clock (ticks.c: the processor's invariant time-stamp counter where
!> it has one, else the monotonic clock in ns), since a phase may be switched several times per
!> event; seconds() converts with the tick rate measured against the wall clock since reset().
!> Phases are exclusive: a phase started while another runs (Comm inside Output, or Output inside
!> Output) pauses it until stopped, so that each tick counts in one phase only and the phases never
!> sum to more than the loop (the run log's Other is what they leave).
module terrace_timers
    use, intrinsic :: iso_c_binding, only: c_int64_t
    use terrace_kinds, only: dp, i8
    use mpi_f08, only: MPI_Wtime
    implicit none
    private

    integer, parameter, public :: t_pair = 1, t_neigh = 2, t_comm = 3, t_output = 4, &
                                  t_search = 5, t_other = 6, n_timers = 6
    character(len=8), parameter, public :: timer_names(n_timers) = &
        [character(len=8) :: 'Pair', 'Neigh', 'Comm', 'Output', 'Search', 'Other']

    integer, parameter :: max_depth = 16

    type, public :: timers_t
        integer(i8) :: ticks(n_timers) = 0_i8
        integer(i8) :: started(n_timers) = 0_i8
        integer(i8) :: tick0 = 0_i8         !< the clock at reset()
        real(dp) :: wall0 = 0.0_dp          !< MPI_Wtime at reset()
        integer :: running(max_depth) = 0   !< the phases started and not stopped, innermost last
        integer :: depth = 0
    contains
        procedure :: reset => timer_reset
        procedure :: start => timer_start
        procedure :: stop => timer_stop
        procedure :: seconds => timer_seconds
    end type timers_t

    interface
        integer(c_int64_t) function ticks() bind(C, name='terrace_ticks')
            import :: c_int64_t
        end function ticks
    end interface

contains

    !> All phases to zero; the clock's rate is measured from here.
    subroutine timer_reset(self)
        class(timers_t), intent(inout) :: self
        self%ticks = 0; self%started = 0
        self%depth = 0
        self%wall0 = MPI_Wtime()
        self%tick0 = ticks()
    end subroutine timer_reset

    !> Phase `which` runs from now; the phase running until now (if any) is paused.
    subroutine timer_start(self, which)
        class(timers_t), intent(inout) :: self
        integer, intent(in) :: which
        integer(i8) :: now
        integer :: outer
        now = ticks()
        if (self%depth > 0) then
            outer = self%running(self%depth)
            self%ticks(outer) = self%ticks(outer) + (now - self%started(outer))
        end if
        if (self%depth < max_depth) then
            self%depth = self%depth + 1
            self%running(self%depth) = which
        end if
        self%started(which) = now
    end subroutine timer_start

    !> Phase `which` stops; the phase it paused (if any) runs again from now. (A stop that is not of
    !> the innermost phase only adds that phase's time since its start.)
    subroutine timer_stop(self, which)
        class(timers_t), intent(inout) :: self
        integer, intent(in) :: which
        integer(i8) :: now
        now = ticks()
        self%ticks(which) = self%ticks(which) + (now - self%started(which))
        if (self%depth == 0) return
        if (self%running(self%depth) /= which) return
        self%depth = self%depth - 1
        if (self%depth > 0) self%started(self%running(self%depth)) = now
    end subroutine timer_stop

    !> Each phase's time in seconds so far (the tick rate from reset() to now).
    function timer_seconds(self) result(seconds)
        class(timers_t), intent(in) :: self
        real(dp) :: seconds(n_timers)
        real(dp) :: wall, per_tick
        integer(i8) :: elapsed
        wall = MPI_Wtime() - self%wall0
        elapsed = ticks() - self%tick0
        per_tick = 0
        if (elapsed > 0 .and. wall > 0) per_tick = wall/real(elapsed, dp)
        seconds = real(self%ticks, dp)*per_tick
    end function timer_seconds

end module terrace_timers
