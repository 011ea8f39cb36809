!> The trajectory output: H5MD frames of the fields asked for (&output trajectory_fields) and the
!> thermo quantities as H5MD observables, written at the sample times the integrator chooses; the
!> file is flushed after a frame when a second of wall time has passed since the last flush, before
!> a checkpoint (a stop request writes one) and when it is closed. Between flushes a small system's
!> frames are kept in memory and written a block at a time (terrace_h5md): a frame that goes only
!> into memory opens no watchdog section (no HDF5 call, no barrier).
!>
!> A mesh scene (add_mesh) also writes its tetrahedra into the file once (/connectivity/tetrahedra,
!> node ids; /parameters/terrace/tetrahedra_index, 0-based rows) and keeps an XDMF sidecar beside
!> it (terrace_xdmf: <trajectory>.xdmf) that lists the frames on disk: rank 0 rewrites it after a
!> flush that put new frames on disk (at most every few seconds of wall time, and never for more
!> than about 1 % of the run's wall time) and when the trajectory is flushed for a checkpoint or
!> closed.
!>
!> Every collective procedure here is one section of the I/O watchdog (terrace_hdf5_io:
!> h5_section_begin/h5_section_end): a rank stuck in HDF5 ends the job with one error line naming
!> the file and &output trajectory_file, whichever rank it is.
module terrace_trajectory
    use terrace_kinds, only: dp, i8
    use terrace_h5md, only: h5md_writer_t, h5md_layout_t
    use terrace_atoms, only: atoms_t
    use terrace_box, only: box_t
    use terrace_units, only: units_t
    use terrace_observables, only: thermo_sample_t
    use terrace_version, only: terrace_version_string
    use terrace_mpi_env, only: world
    use terrace_file_ops, only: remove_at_exit, keep_at_exit, remove_file, output_target
    use terrace_xdmf, only: xdmf_sidecar_path, write_xdmf_mesh
    use terrace_hdf5_io, only: h5_section_begin, h5_section_end
    use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Bcast, MPI_LOGICAL, MPI_CHARACTER, MPI_Wtime
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
        ! a mesh scene's XDMF sidecar
        logical :: mesh = .false.
        type(MPI_Comm) :: comm
        integer :: rank = 0
        character(len=:), allocatable :: xdmf_path
        integer(i8) :: natoms = 0, ntet = 0
        real(dp), allocatable :: times(:)            !< time of every frame written: times(1:ntimes)
        integer(i8) :: ntimes = 0
        integer(i8) :: xdmf_frames = -1              !< frames listed in the sidecar now
        real(dp) :: xdmf_last = -huge(1.0_dp), xdmf_cost = 0
    contains
        procedure :: add_mesh => trajectory_add_mesh
        procedure :: open => trajectory_open
        procedure :: open_append => trajectory_open_append
        procedure :: write => trajectory_write
        procedure :: close => trajectory_close
        procedure :: discard => trajectory_discard
        procedure :: frames => trajectory_frames
        procedure :: flush => trajectory_flush
        procedure, private :: write_sidecar => trajectory_write_sidecar
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
        type(h5md_layout_t) :: layout
        character(len=:), allocatable :: target
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
        ! (through a symbolic link: the file it points to, and the link stays)
        target = output_target(path)
        if (world%rank == 0) call remove_at_exit(target, always=.true.)
        self%comm = comm
        self%natoms = natoms
        call h5_section_begin(label(self), 'creating the file')
        layout = h5md_layout_t(natoms=natoms, dimension=box%dimension, box_lo=box%lo, box_hi=box%hi, &
                               periodic=box%periodic, want_position=self%want_position, &
                               want_velocity=self%want_velocity, want_force=self%want_force, &
                               want_image=self%want_image, masses_by_type=masses, unit_length=ul, unit_time=ut, &
                               unit_energy=ue, unit_velocity=uv, unit_mass=um, &
                               creator_version=terrace_version_string)
        call self%h5%create(path, comm, layout, ok, msg)
        call h5_section_end(comm)
        if (world%rank == 0) then
            call keep_at_exit(target)
            if (.not. ok) rc = remove_file(target)
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
        self%comm = comm
        call h5_section_begin(label(self), 'opening the file to continue it')
        call self%h5%open_append(path, comm, frames, ok, msg)
        call h5_section_end(comm)
        self%active = ok
    end subroutine trajectory_open_append

    !> A mesh scene: the tetrahedra tets(4, ntet) (node ids, the same on every rank) go into the file
    !> (a new trajectory; a continued one has them already) and the XDMF sidecar is written.
    !> Collective; after open or open_append.
    subroutine trajectory_add_mesh(self, tets, natoms, ok, msg)
        class(trajectory_t), intent(inout) :: self
        integer(i8), intent(in), contiguous :: tets(:, :)
        integer(i8), intent(in) :: natoms
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        ok = .true.; msg = ''
        if (.not. self%active) return
        self%mesh = .true.
        self%natoms = natoms
        self%ntet = size(tets, 2, kind=i8)
        self%xdmf_path = xdmf_sidecar_path(self%path)
        call MPI_Comm_rank(self%comm, self%rank)
        call h5_section_begin(label(self), 'writing the mesh')
        if (self%h5%frames_written() == 0) then
            call self%h5%write_connectivity('tetrahedra', tets, ok, msg)
            allocate (self%times(64))
            self%ntimes = 0
        else
            call self%h5%frame_times(self%times, ok, msg)
            self%ntimes = size(self%times, kind=i8)
        end if
        if (ok) call self%write_sidecar(ok, msg)
        call h5_section_end(self%comm)
    end subroutine trajectory_add_mesh

    !> Rewrite the XDMF sidecar with the frames on disk (rank 0 writes; its ok is every rank's).
    !> Collective.
    subroutine trajectory_write_sidecar(self, ok, msg)
        class(trajectory_t), intent(inout) :: self
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer(i8) :: nf
        real(dp) :: t0
        ok = .true.; msg = ''
        if (.not. self%mesh) return
        nf = min(self%h5%frames_flushed(), self%ntimes)
        if (self%rank == 0) then
            t0 = MPI_Wtime()
            call write_xdmf_mesh(self%xdmf_path, self%path, self%natoms, self%ntet, self%times(1:nf), ok, msg)
            self%xdmf_cost = MPI_Wtime() - t0
            self%xdmf_last = MPI_Wtime()
            if (.not. ok) msg = 'XDMF sidecar '//self%xdmf_path//': '//trim(msg)
        end if
        call MPI_Bcast(ok, 1, MPI_LOGICAL, 0, self%comm)
        if (.not. ok) call MPI_Bcast(msg, len(msg), MPI_CHARACTER, 0, self%comm)
        self%xdmf_frames = nf
    end subroutine trajectory_write_sidecar

    !> Flush every frame written so far to disk (before a checkpoint records the frame count).
    !> Collective.
    subroutine trajectory_flush(self, ok, msg)
        class(trajectory_t), intent(inout) :: self
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        ok = .true.; msg = ''
        if (.not. self%active) return
        call h5_section_begin(label(self), 'flushing the file')
        call self%h5%flush(ok, msg)
        if (ok .and. self%mesh) then
            if (self%h5%frames_flushed() /= self%xdmf_frames) call self%write_sidecar(ok, msg)
        end if
        call h5_section_end(self%comm)
        if (.not. ok) msg = self%path//': &output trajectory_file: cannot flush: '//trim(msg)
    end subroutine trajectory_flush

    !> Frames written so far (including those kept from before a restart).
    integer(i8) function trajectory_frames(self)
        class(trajectory_t), intent(in) :: self
        trajectory_frames = 0
        if (self%active) trajectory_frames = self%h5%frames_written()
    end function trajectory_frames

    !> One frame at (step, time), with the thermo sample s as observables; extra(:) are written as
    !> further observables named by extra_names (energy stepping: events, e_terraced, ...); edges:
    !> the box's edges at this frame (a barostat's box; otherwise the box of the file's creation).
    subroutine trajectory_write(self, step, time, atoms, s, ok, msg, extra_names, extra, edges)
        class(trajectory_t), intent(inout) :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        type(atoms_t), intent(in) :: atoms
        type(thermo_sample_t), intent(in) :: s
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=*), intent(in), optional :: extra_names(:)
        real(dp), intent(in), optional :: extra(:)
        real(dp), intent(in), optional :: edges(3)
        integer :: n, k, nobs
        logical :: io, flush_due
        character(len=64) :: names(32)
        real(dp) :: values(32)
        ok = .true.; msg = ''
        if (.not. self%active) return
        n = atoms%nlocal
        ! (both the same on every rank)
        io = self%h5%frame_touches_file()
        flush_due = self%h5%flush_due(flush_interval)
        ! a frame moves at most 3 fields of 3 reals per atom over all ranks (the watchdog's limit; a
        ! block of small frames is at most about 256 KiB)
        if (io .or. flush_due) call h5_section_begin(label(self), 'writing a frame', bytes=72*self%natoms + 262144)
        if (present(edges)) call self%h5%set_edges(edges)
        call self%h5%write_frame(step, time, n, atoms%id(1:n), atoms%type(1:n), x=atoms%x(:, 1:n), &
                                 v=atoms%v(:, 1:n), f=atoms%f(:, 1:n), image=atoms%image(:, 1:n), ok=ok, msg=msg, &
                                 flush=.false.)
        ! observables: sampled with the frame (their step and time are the frame's), flushed below
        nobs = 5
        names(1:5) = [character(len=len(names)) :: 'potential_energy', 'kinetic_energy', 'total_energy', &
                      'temperature', 'pressure']
        values(1:5) = [s%pe, s%ke, s%etotal, s%temp, s%press]
        if (present(extra) .and. present(extra_names)) then
            do k = 1, min(size(extra), size(extra_names), size(names) - 5)
                nobs = nobs + 1
                names(nobs) = extra_names(k); values(nobs) = extra(k)
            end do
        end if
        if (ok) call self%h5%write_frame_observables(names(1:nobs), values(1:nobs), ok, msg)
        if (ok .and. self%mesh) call add_time()
        if (ok .and. flush_due) call self%h5%flush(ok, msg)
        if (ok .and. self%mesh) then
            ! new frames on disk: list them in the sidecar, unless it was rewritten a moment ago
            ! (the rewrite costs O(frames): it is kept to about 1 % of the wall time)
            if (self%h5%frames_flushed() > self%xdmf_frames .and. due_sidecar()) call self%write_sidecar(ok, msg)
        end if
        if (io .or. flush_due) call h5_section_end(self%comm)
        if (.not. ok) msg = self%path//': &output trajectory_file: cannot write a frame: '//trim(msg)

    contains

        subroutine add_time()
            real(dp), allocatable :: grown(:)
            if (self%ntimes == size(self%times, kind=i8)) then
                allocate (grown(max(64_i8, 2*self%ntimes)))
                grown(1:self%ntimes) = self%times(1:self%ntimes)
                call move_alloc(grown, self%times)
            end if
            self%ntimes = self%ntimes + 1
            self%times(self%ntimes) = time
        end subroutine add_time

        !> Rank 0's clock decides for every rank.
        logical function due_sidecar()
            due_sidecar = .false.
            if (self%rank == 0) due_sidecar = MPI_Wtime() - self%xdmf_last >= max(5*flush_interval, 100*self%xdmf_cost)
            call MPI_Bcast(due_sidecar, 1, MPI_LOGICAL, 0, self%comm)
        end function due_sidecar


    end subroutine trajectory_write

    !> Close and delete the file (a run that stops before its first step leaves no trajectory).
    !> Collective.
    subroutine trajectory_discard(self)
        class(trajectory_t), intent(inout) :: self
        integer :: unit, ios
        if (.not. self%active) return
        self%mesh = .false.                   ! close writes no sidecar
        call self%close()
        if (world%rank == 0) then
            open (newunit=unit, file=self%path, status='old', iostat=ios)
            if (ios == 0) close (unit, status='delete')
            if (allocated(self%xdmf_path)) then
                open (newunit=unit, file=self%xdmf_path, status='old', iostat=ios)
                if (ios == 0) close (unit, status='delete')
            end if
        end if
    end subroutine trajectory_discard

    !> Close the file; a mesh trajectory's sidecar then lists every frame. Collective. ok/msg
    !> (optional) report a failure to write the frames kept in memory or the sidecar.
    subroutine trajectory_close(self, ok, msg)
        class(trajectory_t), intent(inout) :: self
        logical, intent(out), optional :: ok
        character(len=*), intent(out), optional :: msg
        logical :: ok_
        character(len=512) :: msg_
        ok_ = .true.; msg_ = ''
        if (self%active) then
            call h5_section_begin(label(self), 'closing the file')
            ! (the frames still kept in memory go into the file here)
            call self%h5%close(ok_, msg_)
            if (.not. ok_) msg_ = 'cannot write the last frames: '//trim(msg_)
            if (ok_ .and. self%mesh .and. self%ntimes /= self%xdmf_frames) then
                ! every frame is on disk now (h5%frames_flushed no longer answers: the writer is closed)
                self%xdmf_frames = -1
                call close_sidecar()
            end if
            call h5_section_end(self%comm)
        end if
        self%active = .false.
        self%mesh = .false.
        if (present(ok)) ok = ok_
        if (present(msg)) msg = msg_
    contains
        subroutine close_sidecar()
            if (self%rank == 0) then
                call write_xdmf_mesh(self%xdmf_path, self%path, self%natoms, self%ntet, self%times(1:self%ntimes), ok_, msg_)
                if (.not. ok_) msg_ = 'XDMF sidecar '//self%xdmf_path//': '//trim(msg_)
            end if
            call MPI_Bcast(ok_, 1, MPI_LOGICAL, 0, self%comm)
            if (.not. ok_) call MPI_Bcast(msg_, len(msg_), MPI_CHARACTER, 0, self%comm)
        end subroutine close_sidecar
    end subroutine trajectory_close

    !> The file and its key, for the watchdog's message.
    function label(self)
        class(trajectory_t), intent(in) :: self
        character(len=:), allocatable :: label
        label = self%path//' (&output trajectory_file)'
    end function label

end module terrace_trajectory
