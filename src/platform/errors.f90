!> The one error path of Terrace.
!>
!> Every error ends the run on every rank with a non-zero exit and a single line on stderr:
!>   terrace: error: <file>: &<group>: <key>: <what is wrong> (allowed: ...)
!> `stop_all` is collective (every rank reaches it with the same message: input checks that
!> every rank performs on the same data). `check_all` is collective too but only some ranks may
!> have failed: the message of the lowest failing rank is printed. `abort_all` is for a failure
!> that only one rank sees in a place where the others cannot be reached: it calls MPI_Abort.
module terrace_errors
    use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
    use, intrinsic :: iso_c_binding, only: c_int
    use mpi_f08, only: MPI_Comm_rank, MPI_Comm_size, MPI_COMM_WORLD, MPI_Finalize, MPI_Abort, MPI_Allreduce, MPI_Barrier, &
                       MPI_Bcast, MPI_INTEGER, MPI_CHARACTER, MPI_MIN, MPI_Initialized, MPI_Finalized
    use terrace_file_ops, only: cleanup_now
    implicit none
    private

    integer, parameter, public :: exit_error = 1
    public :: stop_all, check_all, abort_all, warn, note_broken_hdf5_file

    !> An HDF5 file could not be flushed or closed (a full device): HDF5 1.10 then crashes in its
    !> own clean-up, which MPI_Finalize runs (H5F__close_cb on the half-closed file). stop_all
    !> then ends the processes with _exit after a barrier, without MPI_Finalize, once stdout and
    !> stderr are flushed (the small outputs of a failed run are removed anyway; in-place thermo
    !> files of checkpointed runs are flushed line by line).
    logical :: broken_hdf5 = .false.

    interface
        subroutine c_exit(code) bind(C, name='_exit')
            import :: c_int
            integer(c_int), value :: code
        end subroutine c_exit
        !> A singleton's own Open MPI session directory, removed (mpi_start.c; nothing otherwise).
        subroutine remove_session_base() bind(C, name='terrace_remove_session_base')
        end subroutine remove_session_base
    end interface

contains

    integer function my_rank()
        logical :: up, down
        call MPI_Initialized(up)
        call MPI_Finalized(down)
        my_rank = 0
        if (up .and. .not. down) call MPI_Comm_rank(MPI_COMM_WORLD, my_rank)
    end function my_rank

    !> Collective stop: every rank calls it with the same message.
    subroutine stop_all(msg, code)
        character(len=*), intent(in) :: msg
        integer, intent(in), optional :: code
        integer :: exit_code
        logical :: up
        exit_code = exit_error
        if (present(code)) exit_code = code
        if (my_rank() == 0) then
            write (error_unit, '(a)') 'terrace: error: '//trim(msg)
            flush (error_unit)
        end if
        call cleanup_now()        ! uncommitted temporary outputs and lock files (terrace_file_ops)
        call MPI_Initialized(up)
        if (up .and. broken_hdf5) then
            flush (output_unit); flush (error_unit)
            call MPI_Barrier(MPI_COMM_WORLD)
            call remove_session_base()
            call c_exit(int(exit_code, c_int))
        end if
        if (up) call MPI_Finalize()
        stop exit_code, quiet=.true.
    end subroutine stop_all

    !> Called (on every rank, or on the ranks that saw it) when an HDF5 file could not be written
    !> out: the coming stop_all must not run HDF5's clean-up.
    subroutine note_broken_hdf5_file()
        broken_hdf5 = .true.
    end subroutine note_broken_hdf5_file


    !> Collective check: stops every rank if `ok` is false on any of them.
    subroutine check_all(ok, msg)
        logical, intent(in) :: ok
        character(len=*), intent(in) :: msg
        integer :: mine, first, ierr, nprocs
        character(len=8192) :: text
        ! one rank: nothing to agree on (no call)
        call MPI_Comm_size(MPI_COMM_WORLD, nprocs, ierr)
        if (nprocs == 1 .and. ok) return
        mine = huge(1)
        if (.not. ok) mine = my_rank()
        call MPI_Allreduce(mine, first, 1, MPI_INTEGER, MPI_MIN, MPI_COMM_WORLD, ierr)
        if (first == huge(1)) return
        text = msg
        call MPI_Bcast(text, len(text), MPI_CHARACTER, first, MPI_COMM_WORLD, ierr)
        call stop_all(text)
    end subroutine check_all

    !> Non-collective stop from one rank: message with the rank, then MPI_Abort.
    subroutine abort_all(msg)
        character(len=*), intent(in) :: msg
        character(len=16) :: r
        logical :: up
        write (r, '(i0)') my_rank()
        write (error_unit, '(a)') 'terrace: error (rank '//trim(r)//'): '//trim(msg)
        flush (error_unit)
        call cleanup_now()
        call MPI_Initialized(up)
        if (up) call MPI_Abort(MPI_COMM_WORLD, exit_error)
        stop exit_error, quiet=.true.
    end subroutine abort_all

    !> Warning printed by rank 0 (call collectively or from rank 0).
    subroutine warn(msg)
        character(len=*), intent(in) :: msg
        if (my_rank() == 0) write (error_unit, '(a)') 'terrace: warning: '//trim(msg)
    end subroutine warn

end module terrace_errors
