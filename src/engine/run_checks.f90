!> Failure detection at thermo samples (both integrators): a run that has blown up stops on every
!> rank with one clear line instead of writing garbage.
!>  - a non-finite potential, kinetic or total energy (NaN or infinity);
!>  - an energy blow-up: |E - E0| larger than |K0| + |V0| of the first sample. An NVE run never
!>    legitimately changes its total energy by that much (energy stepping keeps |E - E0| <= h, and
!>    h <= |V0| + K0 is enforced), while an unstable time step overshoots it by orders of magnitude.
!>    With a thermostat E is econserve = E - ecouple (the energy the thermostat put in is no failure).
!> The sample values are global sums (the same on every rank); the checks are still collective.
module terrace_run_checks
    use terrace_kinds, only: dp
    use terrace_observables, only: thermo_sample_t
    use terrace_errors, only: check_all
    implicit none
    private

    type, public :: energy_guard_t
        logical :: started = .false.
        real(dp) :: e0 = 0, scale = 0
    contains
        procedure :: check => guard_check
    end type energy_guard_t

contains

    !> The first call stores the reference E0 and the scale |K0| + |V0|; every call checks.
    subroutine guard_check(self, s)
        class(energy_guard_t), intent(inout) :: self
        type(thermo_sample_t), intent(in) :: s
        character(len=400) :: msg
        logical :: finite
        finite = abs(s%pe) <= huge(1.0_dp) .and. abs(s%ke) <= huge(1.0_dp) .and. abs(s%etotal) <= huge(1.0_dp)
        write (msg, '(a,es12.5,a,i0,a)') 'the energy became NaN or infinite at time ', s%time, ' (step ', s%step, &
            '): the run is unstable (time step or terrace height too large, or atoms overlapping)'
        call check_all(finite, trim(msg))
        if (.not. self%started) then
            self%started = .true.
            self%e0 = s%etotal - s%ecouple
            self%scale = abs(s%ke) + abs(s%pe)
            return
        end if
        if (self%scale <= 0) return
        write (msg, '(a,es12.5,a,es12.5,a,es12.5,a,i0,a)') 'energy blow-up: the total energy changed by ', &
            s%etotal - s%ecouple - self%e0, ' since the start, more than |K0| + |V0| = ', self%scale, ', at time ', s%time, &
            ' (step ', s%step, '): the run is unstable (time step too large)'
        call check_all(abs(s%etotal - s%ecouple - self%e0) <= self%scale, trim(msg))
    end subroutine guard_check

end module terrace_run_checks
