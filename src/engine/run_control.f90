!> Checkpoints and early stops, shared by both integrators.
!>
!> A checkpoint can only be taken at a *safe point*: a moment at which a restart rebuilds exactly
!> the state the uninterrupted run has, so that every later sum runs in the same order and the
!> continuation is bitwise the same. With cell lists that is right after a neighbour-list build
!> (the atoms are freshly wrapped, migrated and sorted; a restart puts every atom back in its slot
!> on the same rank, and its own build reproduces the list); with the all-pairs path every step
!> (velocity Verlet) or window end (energy stepping) is one. Scheduled checkpoints (&output
!> checkpoint_every / checkpoint_interval) force a neighbour-list build at their step, in the
!> uninterrupted run as in any other, so they are safe points by construction.
!>
!> Stop requests (SIGTERM / SIGUSR1 caught by signals.c, or &run walltime_limit running out) are
!> decided at safe points by one MPI_Allreduce (MAX of the signal number and of the wall-clock
!> verdict), so every rank stops at the same step, writes the checkpoint and the run exits with
!> exit_stopped (3). The wall-clock verdict: stop when elapsed + 2 x (longest gap between safe
!> points so far) + 2 x (last checkpoint write) + 1 s would pass the limit.
module terrace_run_control
    use terrace_kinds, only: dp, i8
    use terrace_text, only: fixed
    use terrace_engine, only: engine_t
    use terrace_checkpoint, only: write_checkpoint
    use terrace_named_values, only: named_values_t
    use terrace_signals, only: install_stop_handlers, local_stop_signal, stop_signal_name
    use terrace_mpi_env, only: world
    use terrace_errors, only: check_all, warn
    use terrace_version, only: terrace_version_string
    use mpi_f08, only: MPI_Wtime, MPI_Allreduce, MPI_IN_PLACE, MPI_INTEGER, MPI_MAX
    use, intrinsic :: iso_fortran_env, only: output_unit
    implicit none
    private

    !> What the run control is made from (the deck's &output and &run keys, in the run's units).
    type, public :: control_params_t
        character(len=:), allocatable :: checkpoint_file   !< '' : no checkpoints, no stop on signals
        integer(i8) :: every = 0                 !< velocity Verlet: steps between checkpoints (0: none)
        real(dp) :: interval = 0                 !< energy stepping: time between checkpoints (0: none)
        real(dp) :: walltime_limit = 0           !< seconds (0: none)
        character(len=:), allocatable :: restart_from   !< the checkpoint a restart read (for messages)
        !> what every checkpoint records besides the integrator's values
        character(len=:), allocatable :: integrator, deck_path
        integer(i8) :: deck_hash = 0, seed = 0
        integer :: dimension = 3
        real(dp) :: skin = 0, outer_skin = 0, buffer_drift = 0, buffer_temperature = 0
    end type control_params_t

    type, public :: run_control_t
        logical :: active = .false.              !< a checkpoint file is given
        character(len=:), allocatable :: path
        type(control_params_t) :: p
        integer(i8) :: every = 0                 !< velocity Verlet: steps between checkpoints (0: none)
        real(dp) :: interval = 0                 !< energy stepping: time between checkpoints (0: none)
        integer(i8) :: written = 0               !< scheduled checkpoints so far (this run and those before)
        !> the thermo CSV and trajectory this run writes: the deck's files (1) or their .partN copies
        !> (&system restart_outputs = 'new'); in the checkpoint, so that an appending restart goes on
        !> with the same files
        integer(i8) :: output_part = 1
        real(dp) :: walltime_limit = 0           !< seconds (0: none)
        real(dp) :: wall_start = 0               !< MPI_Wtime at program start
        real(dp) :: last_safe = -1, max_gap = 0, write_seconds = 0
        integer :: stop_signal = 0               !< the signal that stopped the run (0: none)
        logical :: stopped = .false.             !< the run stopped early with a checkpoint
        character(len=:), allocatable :: reason
    contains
        procedure :: init_signals => control_init_signals
        procedure :: init => control_init
        procedure :: stop_requested => control_stop_requested
        procedure :: write => control_write
    end type run_control_t

contains

    !> Catch SIGTERM and SIGUSR1 from the start when the run can write a checkpoint (before the
    !> system is built: a signal during setup stops the run at its first safe point).
    subroutine control_init_signals(self, checkpoint_file)
        class(run_control_t), intent(inout) :: self
        character(len=*), intent(in) :: checkpoint_file
        logical :: ok
        if (len_trim(checkpoint_file) == 0) return
        call install_stop_handlers(ok)
        if (.not. ok) call warn('cannot catch SIGTERM / SIGUSR1: a signal will end the run without a checkpoint')
        self%active = .false.
    end subroutine control_init_signals

    subroutine control_init(self, p, eng, wall_start)
        class(run_control_t), intent(inout) :: self
        type(control_params_t), intent(in) :: p
        type(engine_t), intent(in) :: eng
        real(dp), intent(in) :: wall_start
        logical :: ok
        self%wall_start = wall_start
        self%p = p
        self%active = len_trim(p%checkpoint_file) > 0
        if (.not. self%active) return
        self%path = trim(p%checkpoint_file)
        self%interval = p%interval
        self%every = p%every
        self%walltime_limit = p%walltime_limit
        if (eng%restarted) then
            ok = .true.
            self%written = eng%restart_values%get_i('checkpoints', ok)
            call check_all(ok, trim(p%restart_from)//': &system: read_checkpoint: damaged checkpoint '// &
                           '(no checkpoints counter)')
        end if
    end subroutine control_init

    !> At a safe point: should the run stop now? Collective; the same answer on every rank.
    logical function control_stop_requested(self) result(stop_now)
        class(run_control_t), intent(inout) :: self
        integer :: flags(2)
        real(dp) :: now
        stop_now = .false.
        if (.not. self%active) return
        now = MPI_Wtime()
        if (self%last_safe >= 0) self%max_gap = max(self%max_gap, now - self%last_safe)
        self%last_safe = now
        flags(1) = local_stop_signal()
        flags(2) = 0
        if (self%walltime_limit > 0) then
            if (now - self%wall_start + 2*self%max_gap + 2*self%write_seconds + 1 > self%walltime_limit) flags(2) = 1
        end if
        if (world%nprocs > 1) call MPI_Allreduce(MPI_IN_PLACE, flags, 2, MPI_INTEGER, MPI_MAX, world%comm)
        if (flags(1) /= 0) then
            self%stop_signal = flags(1)
            self%reason = stop_signal_name(flags(1))//' received'
        else if (flags(2) /= 0) then
            self%reason = 'walltime_limit reached'
        end if
        stop_now = flags(1) /= 0 .or. flags(2) /= 0
        self%stopped = stop_now
    end function control_stop_requested

    !> Write the checkpoint: the integrator's values plus what every restart needs (box, masses,
    !> output counters, checkpoint count). scheduled: a checkpoint of the schedule (counted).
    !> Collective; stops every rank with a clear error when it cannot be written.
    subroutine control_write(self, eng, values, step, time, thermo_lines, traj_frames, scheduled)
        class(run_control_t), intent(inout) :: self
        type(engine_t), intent(in) :: eng
        type(named_values_t), intent(inout) :: values
        integer(i8), intent(in) :: step, thermo_lines, traj_frames
        real(dp), intent(in) :: time
        logical, intent(in) :: scheduled
        logical :: ok
        character(len=512) :: msg
        character(len=16) :: tag
        real(dp) :: t0
        integer :: d, t
        t0 = MPI_Wtime()
        if (scheduled) self%written = self%written + 1
        call values%put('step', step)
        call values%put('time', time)
        call values%put('checkpoints', self%written)
        call values%put('thermo_lines', thermo_lines)
        call values%put('trajectory_frames', traj_frames)
        call values%put('output_part', self%output_part)
        call values%put('seed', self%p%seed)
        call values%put('list_skin', self%p%skin)      ! (&neighbor buffer_tolerance: the restart's skin,
        call values%put('list_buffer_drift', self%p%buffer_drift)            !  its estimate and temperature)
        call values%put('list_buffer_temperature', self%p%buffer_temperature)
        call values%put('list_outer_skin', self%p%outer_skin)   ! (with prune_every, the built list's)
        do d = 1, 3
            write (tag, '(i0)') d
            call values%put('box_lo_'//trim(tag), eng%box%lo(d))
            call values%put('box_hi_'//trim(tag), eng%box%hi(d))
            call values%put('domain_grid_'//trim(tag), int(eng%dom%dims(d), i8))   ! (the restart's grid)
        end do
        call values%put('ntypes', int(size(eng%atoms%mass), i8))
        do t = 1, size(eng%atoms%mass)
            write (tag, '(i0)') t
            call values%put('mass_'//trim(tag), eng%atoms%mass(t))
        end do
        if (allocated(eng%mesh_tet)) then       ! a mesh scene: which mesh (checked on restart)
            call values%put('mesh_nodes', eng%natoms)
            call values%put('mesh_elements', size(eng%mesh_tet, 2, kind=i8))
            call values%put('mesh_hash', eng%mesh_hash)
        end if
        call write_checkpoint(self%path, eng%atoms, eng%natoms, self%p%dimension, self%p%integrator, &
                              self%p%deck_path, self%p%deck_hash, terrace_version_string, values, ok, msg)
        call check_all(ok, trim(self%path)//': &output checkpoint_file: '//trim(msg))
        call summary_checkpoint(step, time)
        self%write_seconds = MPI_Wtime() - t0
        if (world%rank == 0) write (output_unit, '(a,i0,a,es16.9,a)') 'checkpoint: step ', step, ', time ', &
            time, ' -> '//self%path//' ('//fixed(self%write_seconds, 3)//' s)'
    end subroutine control_write

    !> The last checkpoint written, in the run summary.
    subroutine summary_checkpoint(step, time)
        use terrace_run_summary, only: summary_put
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        call summary_put('checkpoint/step', step)
        call summary_put('checkpoint/time', time)
    end subroutine summary_checkpoint

end module terrace_run_control
