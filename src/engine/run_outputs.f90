!> The one output path of every integrator: thermo samples (checked by the energy guard; with a
!> thermostat the columns ecouple and econserve follow the integrator's own), trajectory frames and
!> checkpoints (the trajectory flushed first, so that it holds every frame the checkpoint counts),
!> each timed as Output. The files themselves are opened and closed by the run's assembly; this
!> object points at them for the length of the run.
module terrace_run_outputs
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_observables, only: thermo_sample_t
    use terrace_thermo, only: thermo_writer_t
    use terrace_trajectory, only: trajectory_t
    use terrace_run_control, only: run_control_t
    use terrace_run_checks, only: energy_guard_t
    use terrace_named_values, only: named_values_t
    use terrace_timers, only: t_output
    use terrace_errors, only: check_all
    implicit none
    private

    integer, parameter :: max_columns = 32   !< extra thermo columns an integrator may add

    type, public :: run_outputs_t
        type(thermo_writer_t), pointer :: thermo => null()
        type(trajectory_t), pointer :: traj => null()
        type(run_control_t), pointer :: ctl => null()
        logical :: thermostat = .false.         !< thermo has the columns ecouple and econserve
        type(energy_guard_t) :: guard
    contains
        procedure :: sample => out_sample
        procedure :: frame => out_frame
        procedure :: checkpoint => out_checkpoint
    end type run_outputs_t

contains

    !> A thermo line: the sample (its ecouple set by the caller) checked by the energy guard, the
    !> integrator's extra columns, then with a thermostat ecouple and econserve = conserved -
    !> ecouple (conserved: etotal for Verlet, K + k h for energy stepping). Collective.
    subroutine out_sample(self, s, conserved, extra)
        class(run_outputs_t), intent(inout) :: self
        type(thermo_sample_t), intent(in) :: s
        real(dp), intent(in) :: conserved
        real(dp), intent(in), optional :: extra(:)
        real(dp) :: columns(max_columns)
        integer :: n
        call self%guard%check(s)
        n = 0
        if (present(extra)) then
            n = size(extra)
            columns(1:n) = extra
        end if
        if (self%thermostat) then
            columns(n + 1:n + 2) = [s%ecouple, conserved - s%ecouple]
            n = n + 2
        end if
        if (n > 0) then
            call self%thermo%write(s, columns(1:n))
        else
            call self%thermo%write(s)
        end if
    end subroutine out_sample

    !> A trajectory frame at step / event `count` and time `time`, with the integrator's named
    !> values and the present box (a barostat changes it). Collective.
    subroutine out_frame(self, eng, count, time, s, names, values)
        class(run_outputs_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: count
        real(dp), intent(in) :: time
        type(thermo_sample_t), intent(in) :: s
        character(len=*), intent(in), optional :: names(:)
        real(dp), intent(in), optional :: values(:)
        logical :: ok
        character(len=512) :: msg
        call eng%timers%start(t_output)
        call self%traj%write(count, time, eng%atoms, s, ok, msg, names, values, edges=eng%box%length)
        call check_all(ok, trim(msg))
        call eng%timers%stop(t_output)
    end subroutine out_frame

    !> A checkpoint of the integrator's values at step / event `count` and time `time` (scheduled:
    !> one of the schedule's, counted). Collective.
    subroutine out_checkpoint(self, eng, values, count, time, scheduled)
        class(run_outputs_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        type(named_values_t), intent(inout) :: values
        integer(i8), intent(in) :: count
        real(dp), intent(in) :: time
        logical, intent(in) :: scheduled
        logical :: ok
        character(len=512) :: msg
        call eng%timers%start(t_output)
        call self%traj%flush(ok, msg)
        call check_all(ok, trim(msg))
        call self%ctl%write(eng, values, count, time, self%thermo%lines, self%traj%frames(), scheduled)
        call eng%timers%stop(t_output)
    end subroutine out_checkpoint

end module terrace_run_outputs
