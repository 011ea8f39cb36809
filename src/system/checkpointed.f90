!> What holds state that a checkpoint keeps: one procedure writes it to a checkpoint's named values
!> or reads it back, one list of names for both ways, so that the two cannot drift apart. The
!> thermostat, the barostat and each integrator's run (terrace_run_parts) extend this type and
!> override exchange_own with their own variables.
module terrace_checkpointed
    use terrace_named_values, only: named_values_t
    implicit none
    private

    type, public :: checkpointed_t
    contains
        procedure :: exchange_own => no_state
    end type checkpointed_t

contains

    !> The state written to (saving) or read from (ok false when some of it is missing) a
    !> checkpoint's values (none by default).
    subroutine no_state(self, values, saving, ok)
        class(checkpointed_t), intent(inout) :: self
        include 'checkpointed_args.inc'
    end subroutine no_state

end module terrace_checkpointed
