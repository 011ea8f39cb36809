!> The run's calendar: one entry per kind of scheduled thing, for every integrator.
!>
!>   sample      thermo sample            by count (every N steps / events) or by time (multiples of an interval)
!>   frame       trajectory frame         likewise
!>   checkpoint  scheduled checkpoint     by count (Verlet: steps) or by time (energy stepping)
!>   list        neighbour-list expiry    by time (the exact expiry of straight-line motion)
!>   thermostat  thermostat event         by time (Andersen collisions, CSVR rescalings)
!>   barostat    barostat event           by time (Monte Carlo volume moves at multiples of an interval)
!>   finish      end of the run           by time
!>
!> A time entry holds its next time t(k) (huge: none); an entry on a fixed grid also its index
!> n(k), t(k) = n(k) interval(k). Energy stepping ends each window at next(), the earliest entry,
!> and asks which entries are due there; velocity Verlet asks count_due(k, step) for the entries
!> counted in steps. The wall-time check is made at the safe points that follow from the list
!> entry (run_control).
module terrace_calendar
    use terrace_kinds, only: dp, i8
    implicit none
    private

    integer, parameter, public :: cal_sample = 1, cal_frame = 2, cal_checkpoint = 3, cal_list = 4, &
                                  cal_thermostat = 5, cal_finish = 6, cal_barostat = 7
    integer, parameter :: n_entries = 7

    type, public :: calendar_t
        real(dp) :: t(n_entries) = huge(1.0_dp)     !< next time of each entry (huge: none)
        integer(i8) :: n(n_entries) = 1             !< grid entries: index of the next point
        real(dp) :: interval(n_entries) = 0         !< grid entries: spacing (0: not on a grid)
        integer(i8) :: every(n_entries) = 0         !< counted entries: due every this many (0: never)
    contains
        procedure :: next => cal_next
        procedure :: due => cal_due
        procedure :: on_grid => cal_on_grid
        procedure :: reached => cal_reached
        procedure :: count_due => cal_count_due
    end type calendar_t

contains

    !> The earliest entry's time.
    pure real(dp) function cal_next(self) result(t)
        class(calendar_t), intent(in) :: self
        t = minval(self%t)
    end function cal_next

    !> Entry k is due at time t.
    pure logical function cal_due(self, k, t)
        class(calendar_t), intent(in) :: self
        integer, intent(in) :: k
        real(dp), intent(in) :: t
        cal_due = t >= self%t(k)
    end function cal_due

    !> Entry k at the multiples of interval (0: none), from the index n on.
    pure subroutine cal_on_grid(self, k, interval, n)
        class(calendar_t), intent(inout) :: self
        integer, intent(in) :: k
        real(dp), intent(in) :: interval
        integer(i8), intent(in) :: n
        self%interval(k) = interval
        self%n(k) = n
        self%t(k) = huge(1.0_dp)
        if (interval > 0) self%t(k) = n*interval
    end subroutine cal_on_grid

    !> A grid entry is due at time t: it moves on to its next point (n counts them).
    logical function cal_reached(self, k, t) result(reached)
        class(calendar_t), intent(inout) :: self
        integer, intent(in) :: k
        real(dp), intent(in) :: t
        reached = t >= self%t(k)
        if (.not. reached) return
        self%n(k) = self%n(k) + 1
        self%t(k) = self%n(k)*self%interval(k)
    end function cal_reached

    !> A counted entry is due after step / event count (never when its every is 0).
    pure logical function cal_count_due(self, k, count) result(due)
        class(calendar_t), intent(in) :: self
        integer, intent(in) :: k
        integer(i8), intent(in) :: count
        due = .false.
        if (self%every(k) > 0) due = mod(count, self%every(k)) == 0
    end function cal_count_due

end module terrace_calendar
