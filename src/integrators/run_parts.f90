!> What an integrator's run is made from, held in one record for its procedures: the engine (atoms,
!> box, potential, neighbour list), the thermostat, the barostat (barostat_none_t for none) and the
!> outputs. The run's assembly (app/terrace.f90) owns them and hands the integrator this record of
!> pointers to them; each integrator's run record extends it with its own state
!> (velocity Verlet's vv_run_t, energy stepping's es_run_t, event-driven dynamics' ed_run_t) and
!> its own values of a checkpoint, written and read in one place (exchange_own). The checkpoint itself, with the
!> thermostat's and the barostat's state, and their restore are here, once for every integrator.
module terrace_run_parts
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_thermostat, only: thermostat_t
    use terrace_barostat, only: barostat_t
    use terrace_run_outputs, only: run_outputs_t
    use terrace_named_values, only: named_values_t
    use terrace_checkpointed, only: checkpointed_t
    implicit none
    private

    type, extends(checkpointed_t), public :: run_parts_t
        type(engine_t), pointer :: eng => null()
        class(thermostat_t), pointer :: ts => null()
        class(barostat_t), pointer :: bs => null()
        type(run_outputs_t), pointer :: out => null()
    contains
        procedure, non_overridable :: checkpoint => parts_checkpoint
        procedure, non_overridable :: restore_coupling => parts_restore_coupling
    end type run_parts_t

contains

    !> A checkpoint at step or event `count` and time `time` (scheduled: one of the schedule's,
    !> counted), through the run's outputs: the integrator's own values, then the thermostat's and
    !> the barostat's state. Collective.
    subroutine parts_checkpoint(self, count, time, scheduled)
        class(run_parts_t), intent(inout) :: self
        integer(i8), intent(in) :: count
        real(dp), intent(in) :: time
        logical, intent(in) :: scheduled
        type(named_values_t) :: values
        logical :: ok
        ok = .true.
        call self%exchange_own(values, .true., ok)
        if (self%ts%active()) call self%ts%save(values)
        if (self%bs%active()) call self%bs%exchange_own(values, .true., ok)
        call self%out%checkpoint(self%eng, values, count, time, scheduled)
    end subroutine parts_checkpoint

    !> The thermostat's and the barostat's state from a checkpoint's values (ok false when some of
    !> it is missing).
    subroutine parts_restore_coupling(self, values, ok)
        class(run_parts_t), intent(inout) :: self
        type(named_values_t), intent(inout) :: values
        logical, intent(inout) :: ok
        if (self%ts%active()) call self%ts%restore(values, ok)
        if (self%bs%active()) call self%bs%exchange_own(values, .false., ok)
    end subroutine parts_restore_coupling

end module terrace_run_parts
