!> The trajectory output: H5MD frames of the fields asked for (&output trajectory_fields) and the
!> thermo quantities as H5MD observables, written at the sample times the integrator chooses; the
!> file is flushed after a frame when a second of wall time has passed since the last flush, and
!> when it is closed.
module terrace_trajectory
    use terrace_kinds, only: dp, i8
    use terrace_h5md, only: h5md_writer_t
    use terrace_atoms, only: atoms_t
    use terrace_box, only: box_t
    use terrace_units, only: units_t
    use terrace_observables, only: thermo_sample_t
    use terrace_version, only: terrace_version_string
    use terrace_mpi_env, only: world
    use terrace_file_ops, only: remove_at_exit, keep_at_exit, remove_file
    use mpi_f08, only: MPI_Comm
    implicit none
    private

    !> Wall time (s) between flushes of the file: frames written less than this after the last
    !> flush are flushed with a later frame or at the end (a flush costs several times the data of a
    !> small system's frame; a killed run loses at most this much wall time of frames).
    real(dp), parameter :: flush_interval = 1.0_dp

    type, public :: trajectory_t
        type(h5md_writer_t) :: h5
        logical :: active = .false.
        character(len=:), allocatable :: path
        logical :: want_position = .false., want_velocity = .false., want_force = .false., want_image = .false.
    contains
        procedure :: open => trajectory_open
        procedure :: open_append => trajectory_open_append
        procedure :: write => trajectory_write
        procedure :: close => trajectory_close
        procedure :: discard => trajectory_discard
        procedure :: frames => trajectory_frames
        procedure :: flush => trajectory_flush
    end type trajectory_t

contains

    subroutine trajectory_open(self, path, fields, comm, natoms, box, masses, units, ok, msg)
        class(trajectory_t), intent(inout) :: self
        character(len=*), intent(in) :: path, fields
        type(MPI_Comm), intent(in) :: comm
        integer(i8), intent(in) :: natoms
        type(box_t), intent(in) :: box
        real(dp), intent(in) :: masses(:)
        type(units_t), intent(in) :: units
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=16) :: ul, ut, ue, uv, um
        integer :: rc
        ok = .true.; msg = ''
        if (len_trim(path) == 0) return
        self%path = path
        self%want_position = index(fields, 'position') > 0
        self%want_velocity = index(fields, 'velocity') > 0
        self%want_force = index(fields, 'force') > 0
        self%want_image = index(fields, 'image') > 0
        if (units%name == 'metal') then
            ul = 'Angstrom'; ut = 'ps'; ue = 'eV'; uv = 'Angstrom ps-1'; um = 'u'
        else
            ul = ''; ut = ''; ue = ''; uv = ''; um = ''
        end if
        ! a trajectory that cannot be created (a full device) is not left behind, even when the
        ! job is aborted (terrace_hdf5_io: h5_agree)
        if (world%rank == 0) call remove_at_exit(path, always=.true.)
        call self%h5%create(path, comm, natoms, box%dimension, box%lo, box%hi, box%periodic, self%want_position, &
                            self%want_velocity, self%want_force, self%want_image, masses, trim(ul), trim(ut), &
                            trim(ue), trim(uv), trim(um), terrace_version_string, ok, msg)
        if (world%rank == 0) then
            call keep_at_exit(path)
            if (.not. ok) rc = remove_file(path)
        end if
        self%active = ok
    end subroutine trajectory_open

    !> Continue an existing trajectory after a restart: the file keeps its first `frames` frames
    !> (later ones, written by a run killed after its checkpoint, are dropped) and the run appends.
    subroutine trajectory_open_append(self, path, comm, frames, ok, msg)
        class(trajectory_t), intent(inout) :: self
        character(len=*), intent(in) :: path
        type(MPI_Comm), intent(in) :: comm
        integer(i8), intent(in) :: frames
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        ok = .true.; msg = ''
        if (len_trim(path) == 0) return
        self%path = path
        call self%h5%open_append(path, comm, frames, ok, msg)
        self%active = ok
    end subroutine trajectory_open_append

    !> Flush every frame written so far to disk (before a checkpoint records the frame count).
    !> Collective.
    subroutine trajectory_flush(self, ok, msg)
        class(trajectory_t), intent(inout) :: self
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        ok = .true.; msg = ''
        if (self%active) call self%h5%flush(ok, msg)
        if (.not. ok) msg = self%path//': &output trajectory_file: cannot flush: '//trim(msg)
    end subroutine trajectory_flush

    !> Frames written so far (including those kept from before a restart).
    integer(i8) function trajectory_frames(self)
        class(trajectory_t), intent(in) :: self
        trajectory_frames = 0
        if (self%active) trajectory_frames = self%h5%frames_written()
    end function trajectory_frames

    !> One frame at (step, time), with the thermo sample s as observables; extra(:) are written as
    !> further observables named by extra_names (energy stepping: events, e_terraced, ...).
    subroutine trajectory_write(self, step, time, atoms, s, ok, msg, extra_names, extra)
        class(trajectory_t), intent(inout) :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        type(atoms_t), intent(in) :: atoms
        type(thermo_sample_t), intent(in) :: s
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=*), intent(in), optional :: extra_names(:)
        real(dp), intent(in), optional :: extra(:)
        integer :: n, k
        ok = .true.; msg = ''
        if (.not. self%active) return
        n = atoms%nlocal
        call self%h5%write_frame(step, time, n, atoms%id(1:n), atoms%type(1:n), x=atoms%x(:, 1:n), &
                                 v=atoms%v(:, 1:n), f=atoms%f(:, 1:n), image=atoms%image(:, 1:n), ok=ok, msg=msg, &
                                 flush=.false.)
        if (.not. ok) then
            msg = self%path//': &output trajectory_file: cannot write a frame: '//trim(msg)
            return
        end if
        ! observables: sampled with the frame (their step and time are the frame's), flushed below
        call observable('potential_energy', s%pe)
        call observable('kinetic_energy', s%ke)
        call observable('total_energy', s%etotal)
        call observable('temperature', s%temp)
        call observable('pressure', s%press)
        if (present(extra) .and. present(extra_names)) then
            do k = 1, size(extra)
                call observable(trim(extra_names(k)), extra(k))
            end do
        end if
        if (ok) call self%h5%flush(ok, msg, min_interval=flush_interval)
        if (.not. ok) msg = self%path//': &output trajectory_file: cannot write a frame: '//trim(msg)

    contains

        subroutine observable(name, value)
            character(len=*), intent(in) :: name
            real(dp), intent(in) :: value
            if (ok) call self%h5%write_observable(name, step, time, value, ok, msg, flush=.false., per_frame=.true.)
        end subroutine observable

    end subroutine trajectory_write

    !> Close and delete the file (a run that stops before its first step leaves no trajectory).
    !> Collective.
    subroutine trajectory_discard(self)
        class(trajectory_t), intent(inout) :: self
        integer :: unit, ios
        if (.not. self%active) return
        call self%close()
        if (world%rank == 0) then
            open (newunit=unit, file=self%path, status='old', iostat=ios)
            if (ios == 0) close (unit, status='delete')
        end if
    end subroutine trajectory_discard

    subroutine trajectory_close(self)
        class(trajectory_t), intent(inout) :: self
        if (self%active) call self%h5%close()
        self%active = .false.
    end subroutine trajectory_close

end module terrace_trajectory
