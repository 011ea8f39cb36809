!> Stop requests from the batch system: SIGTERM and SIGUSR1 set a flag in a small C handler
!> (signals.c); the integrators poll it at their safe points through stop_requested, which is
!> collective (one MPI_Allreduce of a logical), so that every rank stops at the same step, writes
!> the checkpoint and exits with exit_stopped. The wall-clock limit (&run walltime_limit) is
!> decided in the same reduction.
module terrace_signals
    use, intrinsic :: iso_c_binding, only: c_int, c_char
    implicit none
    private

    !> Exit status of a run that stopped early with a checkpoint (walltime_limit or a signal):
    !> resubmit it with &system read_checkpoint.
    integer, parameter, public :: exit_stopped = 3

    public :: install_stop_handlers, stop_signal_name, local_stop_signal, watchdog_arm, watchdog_disarm, test_stall

    interface
        integer(c_int) function c_install() bind(C, name='terrace_install_stop_handlers')
            import :: c_int
        end function c_install
        integer(c_int) function c_signal() bind(C, name='terrace_stop_signal')
            import :: c_int
        end function c_signal
        integer(c_int) function c_sigterm() bind(C, name='terrace_sigterm_number')
            import :: c_int
        end function c_sigterm
        integer(c_int) function c_sigusr1() bind(C, name='terrace_sigusr1_number')
            import :: c_int
        end function c_sigusr1
        integer(c_int) function c_arm(seconds, msg, len, status) bind(C, name='terrace_watchdog_arm')
            import :: c_int, c_char
            integer(c_int), value :: seconds, len, status
            character(kind=c_char), intent(in) :: msg(*)
        end function c_arm
        subroutine watchdog_disarm() bind(C, name='terrace_watchdog_disarm')
        end subroutine watchdog_disarm
        subroutine c_stall(seconds, block_alarm) bind(C, name='terrace_test_stall')
            import :: c_int
            integer(c_int), value :: seconds, block_alarm
        end subroutine c_stall
    end interface

contains

    !> Catch SIGTERM and SIGUSR1 from now on. ok = .false. if the handler could not be installed.
    subroutine install_stop_handlers(ok)
        logical, intent(out) :: ok
        ok = c_install() == 0
    end subroutine install_stop_handlers

    !> After `seconds` (unless watchdog_disarm is called first) print msg on stderr, remove the
    !> registered temporary files and exit with `status` (signals.c): for library calls that may
    !> never return (HDF5 stuck in a collective after a failed write, or spinning on a damaged
    !> file). Not collective.
    subroutine watchdog_arm(seconds, msg, status)
        integer, intent(in) :: seconds, status
        character(len=*), intent(in) :: msg
        integer(c_int) :: rc
        rc = c_arm(int(seconds, c_int), msg, int(len(msg), c_int), int(status, c_int))
    end subroutine watchdog_arm

    !> Test hook only (TERRACE_TEST_STALL_RANK): stop here for `seconds` as a process stuck in an
    !> I/O call would; with block_alarm this process's own watchdog cannot report (SIGALRM is
    !> ignored: a process that cannot run at all), so another rank's must (signals.c).
    subroutine test_stall(seconds, block_alarm)
        integer, intent(in) :: seconds
        logical, intent(in) :: block_alarm
        call c_stall(int(seconds, c_int), merge(1_c_int, 0_c_int, block_alarm))
    end subroutine test_stall

    !> The stop signal this process received (0: none). Not collective.
    integer function local_stop_signal()
        local_stop_signal = int(c_signal())
    end function local_stop_signal

    function stop_signal_name(sig) result(name)
        integer, intent(in) :: sig
        character(len=:), allocatable :: name
        if (sig == c_sigterm()) then
            name = 'SIGTERM'
        else if (sig == c_sigusr1()) then
            name = 'SIGUSR1'
        else
            name = 'a signal'
        end if
    end function stop_signal_name

end module terrace_signals
