!> Per-phase wall-clock timers (pair, neighbour, communication, output, event search, other).
module terrace_timers
    use terrace_kinds, only: dp
    use mpi_f08, only: MPI_Wtime
    implicit none
    private

    integer, parameter, public :: t_pair = 1, t_neigh = 2, t_comm = 3, t_output = 4, &
                                  t_search = 5, t_other = 6, n_timers = 6
    character(len=8), parameter, public :: timer_names(n_timers) = &
        [character(len=8) :: 'Pair', 'Neigh', 'Comm', 'Output', 'Search', 'Other']

    type, public :: timers_t
        real(dp) :: total(n_timers) = 0.0_dp
        real(dp) :: started(n_timers) = 0.0_dp
    contains
        procedure :: start => timer_start
        procedure :: stop => timer_stop
    end type timers_t

contains

    subroutine timer_start(self, which)
        class(timers_t), intent(inout) :: self
        integer, intent(in) :: which
        self%started(which) = MPI_Wtime()
    end subroutine timer_start

    subroutine timer_stop(self, which)
        class(timers_t), intent(inout) :: self
        integer, intent(in) :: which
        self%total(which) = self%total(which) + (MPI_Wtime() - self%started(which))
    end subroutine timer_stop

end module terrace_timers
