!> H5MD 1.1 trajectories (https://nongnu.org/h5md/h5md.html), written in parallel through MPI-IO.
!>
!> Layout (shapes as C / h5py sees them; N atoms, D = dimension):
!>
!>     h5md                     +-- version = [1, 1]
!>      \-- author              +-- name
!>      \-- creator             +-- name = 'Terrace', version
!>      \-- modules/units       +-- version = [1, 0], system = 'SI'     (only when units are given)
!>     particles/all
!>      \-- box                 +-- dimension = D, boundary = 'periodic' | 'none' (D entries)
!>      |    \-- edges                                 (time-dependent: hi - lo at every frame)
!>      |         \-- step: Integer[variable]          (int64; shared by every element below)
!>      |         \-- time: Float[variable]            (float64; shared likewise)
!>      |         \-- value: Float[variable][D]
!>      \-- position, velocity, force, image           (each optional)
!>      |    \-- step: Integer[variable]               (hard link to box/edges/step)
!>      |    \-- time: Float[variable]                 (hard link to box/edges/time)
!>      |    \-- value: Float[variable][N][D]          (image: Integer; chunked, extendible)
!>      \-- id: Integer[N]                             (int64, 1..N)
!>      \-- species: Integer[N]                        (int32, the atom type)
!>      \-- mass: Float[N]                             (masses_by_type(type))
!>     observables/<name>
!>      \-- step, time, value: [variable]                (step, time: hard links to box/edges/ when
!>                                                       the observable is written with every frame)
!>     connectivity/<name>: Integer[M][T]              (optional, write_connectivity: H5MD 1.1
!>      +-- particles_group = 'all'                      tuples of particle ids, int64; a mesh's
!>                                                       tetrahedra: T = 4)
!>     parameters/terrace/<name>_index: Integer[M][T]  (the same tuples as 0-based rows of the
!>                                                       id-ordered particle arrays, int32: what
!>                                                       an XDMF Topology reads)
!>
!> edges is a time-dependent element (one row per frame: the box of that frame, set by set_edges
!> before write_frame when a barostat changes it; readers such as MDAnalysis read
!> box/edges/value[frame] unconditionally, so a fixed box is written per frame too); the reader (h5md_reader.f90) accepts both forms (a fixed edges dataset, as earlier Terrace
!> files have, or the time-dependent group).
!>
!> Atoms are stored in global id order (row id - 1) on any number of ranks: write_frame sends every
!> atom to the rank that owns its id in a block distribution of 1..N (one MPI_Alltoallv; nothing is
!> gathered on one rank), and each rank then writes its block as one hyperslab with a collective
!> MPI-IO transfer. write_frame flushes the file after the frame unless told not to (the trajectory
!> output flushes after its observables, at most once a second: writer_flush's min_interval), so a
!> killed run leaves a readable file up to its last flushed frame. Frames written without a flush
!> (and the per-frame observables written with them) are kept in memory, up to a block of frames of
!> about 256 KiB over all atoms (at most 512 frames; a large system's block is one frame), and the
!> block goes into the file with one extension and one hyperslab per dataset when it is full, at a
!> flush and at close: a small system's frame then costs a copy, not a dozen HDF5 calls. Unit strings follow the H5MD
!> units module; the engine passes 'Angstrom', 'ps', 'eV', 'Angstrom ps-1', 'u' for metal units (the
!> spelling MDAnalysis reads) and '' everywhere for reduced (lj) units.
!>
!> Every procedure is collective over the writer's communicator and returns errors as ok/msg (the
!> same ok on every rank); the HDF5 calls go through terrace_hdf5_io.
module terrace_h5md
    use, intrinsic :: iso_c_binding, only: c_loc
    use terrace_kinds, only: dp, i8
    use terrace_id_blocks, only: id_block, exchange_plan
    use terrace_errors, only: note_broken_hdf5_file
    use terrace_hdf5_io, only: h5_status_t, h5_group, h5_library, h5_agree, h5_writer_closed, h5_guard_begin, &
                               h5_guard_end, h5_open_file, h5_create, h5_append, &
                               h5_transfer_list, h5_make_fixed, h5_make_series, h5_extend, h5_dataset_dims, &
                               h5_write_slab, h5_read_slab, h5_attr_int, h5_attr_text, h5_attr_text_list, &
                               h5_attr_vltext
    use terrace_h5md_reader, only: h5md_read_frame, h5md_frame_t
    use mpi_f08, only: MPI_Comm, MPI_Comm_dup, MPI_Comm_free, MPI_Comm_rank, MPI_Comm_size, &
                       MPI_Allreduce, MPI_Alltoallv, MPI_Bcast, MPI_IN_PLACE, MPI_LOGICAL, &
                       MPI_LOR, MPI_SUM, MPI_INTEGER, MPI_INTEGER8, MPI_DOUBLE_PRECISION, &
                       MPI_CHARACTER, MPI_Wtime
    use hdf5, only: hid_t, hsize_t, h5gcreate_f, h5gclose_f, h5gopen_f, h5dopen_f, h5dclose_f, h5fclose_f, &
                    h5fflush_f, h5lexists_f, h5lcreate_hard_f, h5gn_members_f, h5gget_obj_info_idx_f, h5pclose_f, &
                    h5kind_to_type, H5_INTEGER_KIND, H5F_SCOPE_GLOBAL_F, H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER, &
                    H5T_STD_I64LE, H5T_STD_I32LE, H5T_IEEE_F64LE
    implicit none
    private

    public :: h5md_writer_t, h5md_layout_t
    public :: h5md_read_frame, h5md_frame_t   ! the reader's, named here for the callers of the writer's module

    integer, parameter :: nel = 4                       !< time-dependent particle elements
    integer, parameter :: e_pos = 1, e_vel = 2, e_force = 3, e_image = 4
    character(len=8), parameter :: el_name(nel) = [character(len=8) :: 'position', 'velocity', 'force', 'image']
    character(len=*), parameter :: pgroup = '/particles/all'
    integer(hsize_t), parameter :: chunk_bytes = 1048576   !< largest chunk of the per-atom series (one frame)
    integer(hsize_t), parameter :: small_chunk_bytes = 65536 !< several frames of a small system per chunk
    integer(hsize_t), parameter :: chunk_scalar = 512      !< chunk of the edges series
    integer(i8), parameter :: block_bytes = 262144         !< frames kept in memory: about this many bytes
    integer, parameter :: max_block_frames = 512            !< and at most this many frames


    !> What a new trajectory holds: natoms atoms in `dimension` dimensions, the box (lo, hi,
    !> periodic), the time-dependent elements wanted (image needs position), masses_by_type(t) the
    !> mass of atom type t (types run 1..size(masses_by_type)), the unit strings ('': no unit
    !> attribute), the creator's version, and the author (not allocated: $USER).
    type :: h5md_layout_t
        integer(i8) :: natoms = 0
        integer :: dimension = 3
        real(dp) :: box_lo(3) = 0, box_hi(3) = 0
        logical :: periodic(3) = .false.
        logical :: want_position = .false., want_velocity = .false., want_force = .false., want_image = .false.
        real(dp), allocatable :: masses_by_type(:)
        character(len=64) :: unit_length = '', unit_time = '', unit_energy = '', unit_velocity = '', unit_mass = ''
        character(len=64) :: creator_version = ''
        character(len=:), allocatable :: author
    end type h5md_layout_t

    !> write_frame's work arrays, kept from frame to frame: for a large system, allocating and
    !> first-touching them anew at every frame cost about as much as the HDF5 write itself.
    type :: frame_work_t
        integer :: send_capacity = -1, recv_capacity = -1
        integer, allocatable :: dest(:), row(:)           !< rank owning each local atom; row of each received one
        integer(i8), allocatable :: sint(:, :), rint(:, :) !< id, (type at frame 0), image
        real(dp), allocatable :: sreal(:, :), rreal(:, :)  !< position, velocity, force
        logical, allocatable :: seen(:)
        real(dp), allocatable :: rbuf(:, :)                 !< one element of this rank's block, in id order
        integer, allocatable :: ibuf(:, :)
    end type frame_work_t

    !> The columns of one atom in write_frame's exchange: reals (position, velocity, force: D each,
    !> element e from roff(e) + 1; wr in all) and integers (id, the type in row it at the first
    !> frame (0: not sent), image in rows im+1 .. im+D; wi in all).
    type :: frame_columns_t
        integer :: wr = 0, wi = 0, it = 0, im = 0
        integer :: roff(nel) = 0
    end type frame_columns_t

    type :: observable_t
        character(len=:), allocatable :: name
        integer(hid_t) :: step = -1, time = -1, value = -1
        integer(hsize_t) :: n = 0
        logical :: per_frame = .false.                    !< step and time are the frames' (hard links)
        integer(hsize_t) :: ndisk = 0                     !< per_frame: values in the file; n - ndisk in buf
        real(dp), allocatable :: buf(:)
    end type observable_t

    type, public :: h5md_writer_t
        private
        logical :: opened = .false.
        character(len=:), allocatable :: path
        type(MPI_Comm) :: comm
        integer :: rank = 0, nprocs = 1
        integer(hid_t) :: file = -1, dxpl = -1
        integer(hid_t) :: dxpl_rank0 = -1                  !< independent: the small series rank 0 writes alone
        integer(i8) :: natoms = 0
        integer :: dimension = 3
        logical :: want(nel) = .false.
        integer(hid_t) :: value(nel) = -1
        integer(hid_t) :: step = -1, time = -1             !< box/edges/step, time (linked by the others)
        integer(hid_t) :: edges_value = -1                 !< box/edges/value
        real(dp) :: edges(3) = 0
        integer(hid_t) :: id = -1, species = -1, mass = -1
        integer(hsize_t) :: nframes = 0
        integer(hsize_t) :: nflushed = 0                   !< frames on disk at the last flush
        integer(i8) :: last_step = 0
        real(dp) :: last_flush = 0                          !< rank 0's MPI_Wtime at the last writer_flush
        integer(i8) :: first = 1, nmine = 0               !< this rank's block of ids: first .. first+nmine-1
        real(dp), allocatable :: masses_by_type(:)
        character(len=:), allocatable :: unit_time
        type(observable_t), allocatable :: obs(:)
        integer :: nobs = 0
        integer, allocatable :: frame_obs(:)               !< write_frame_observables: index in obs of each name
        type(frame_work_t) :: work
        !> frames kept in memory: nbuf of them (frames ndisk+1 .. ndisk+nbuf), at most `block`
        integer :: block = 1, nbuf = 0
        integer(hsize_t) :: ndisk = 0                      !< frames in the file's datasets
        real(dp), allocatable :: breal(:, :, :, :)         !< (D, nmine, block, 3): position, velocity, force
        integer, allocatable :: bimage(:, :, :)            !< (D, nmine, block)
        integer(i8), allocatable :: bstep(:)
        real(dp), allocatable :: btime(:), bedges(:, :)
    contains
        procedure :: create => writer_create
        procedure :: open_append => writer_open_append
        procedure :: write_frame => writer_write_frame
        procedure :: set_edges => writer_set_edges
        procedure :: write_observable => writer_write_observable
        procedure :: write_frame_observables => writer_write_frame_observables
        procedure :: flush => writer_flush
        procedure :: close => writer_close
        procedure :: is_open => writer_is_open
        procedure :: frames_written => writer_frames_written
        procedure :: frames_flushed => writer_frames_flushed
        procedure :: frame_times => writer_frame_times
        procedure :: write_connectivity => writer_write_connectivity
        procedure :: frame_touches_file => writer_frame_touches_file
        procedure :: flush_due => writer_flush_due
    end type h5md_writer_t


contains

    ! ============================================================== writer

    !> Create (truncate) `path` and lay out the H5MD structure the layout describes (see
    !> h5md_layout_t); species, id and mass are written at the first frame.
    subroutine writer_create(self, path, comm, layout, ok, msg)
        class(h5md_writer_t), intent(inout) :: self
        character(len=*), intent(in) :: path
        type(MPI_Comm), intent(in) :: comm
        type(h5md_layout_t), intent(in) :: layout
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(h5_status_t) :: st
        integer(hid_t) :: g, gp
        integer :: err

        if (already_open(self, 'create', ok, msg)) return
        call check_layout(layout, st)
        if (.not. st%ok) then
            ok = .false.; msg = st%msg; return
        end if

        call begin_open(self, path, comm, st)
        if (.not. st%ok) then
            ok = .false.; msg = st%msg; return
        end if
        self%natoms = layout%natoms
        self%dimension = layout%dimension
        self%want = [layout%want_position, layout%want_velocity, layout%want_force, layout%want_image]
        self%masses_by_type = layout%masses_by_type
        self%unit_time = trim(layout%unit_time)
        self%nframes = 0; self%last_step = 0; self%nflushed = 0; self%ndisk = 0
        self%nobs = 0
        if (allocated(self%obs)) deallocate (self%obs)
        allocate (self%obs(4))
        call id_block(layout%natoms, self%nprocs, self%rank, self%first, self%nmine)
        call set_block(self)

        ! file (collective): MPI-IO driver, HDF5 file format version 2 (1.8 object headers)
        call h5_open_file(st, self%path, h5_create, self%file, self%comm, collective_metadata=.true., &
                          label=trim(self%path)//' (&output trajectory_file)')
        if (self%file < 0 .or. .not. st%ok) then
            call MPI_Comm_free(self%comm)
            ok = .false.; msg = 'h5md: cannot create '//self%path
            if (.not. st%ok) msg = trim(msg)//' ('//trim(st%msg)//')'
            return
        end if
        call h5_transfer_list(st, .true., self%dxpl)
        ! step, time, edges and observables (one value per frame, from rank 0): an independent write
        ! skips the collective machinery that costs more than such a value
        call h5_transfer_list(st, .false., self%dxpl_rank0)

        call write_h5md_group(self, layout, st)
        call h5gcreate_f(self%file, 'particles', g, err); call st%check(err, 'create particles')
        call h5gcreate_f(g, 'all', gp, err); call st%check(err, 'create particles/all')
        call create_box(self, gp, layout, st)
        call create_elements(self, gp, layout, st)
        ! time-independent per-atom data (written at the first frame)
        call h5_make_fixed(st, gp, 'id', H5T_STD_I64LE, [int(layout%natoms, hsize_t)], self%id)
        call h5_make_fixed(st, gp, 'species', H5T_STD_I32LE, [int(layout%natoms, hsize_t)], self%species)
        call h5_make_fixed(st, gp, 'mass', H5T_IEEE_F64LE, [int(layout%natoms, hsize_t)], self%mass)
        call h5_attr_vltext(st, self%mass, 'unit', trim(layout%unit_mass))
        call h5gclose_f(gp, err)
        call h5gclose_f(g, err)

        call end_open(self, st, ok, msg)
    end subroutine writer_create

    !> The layout's own consistency (the same on every rank, so no agreement is needed).
    subroutine check_layout(layout, st)
        type(h5md_layout_t), intent(in) :: layout
        type(h5_status_t), intent(inout) :: st
        integer :: k
        if (layout%natoms < 1) call st%fail('h5md: create: natoms must be at least 1')
        if (layout%dimension < 1 .or. layout%dimension > 3) call st%fail('h5md: create: dimension must be 1, 2 or 3')
        if (layout%want_image .and. .not. layout%want_position) &
            call st%fail('h5md: create: image needs position (H5MD links their step and time)')
        if (.not. allocated(layout%masses_by_type)) then
            call st%fail('h5md: create: masses_by_type is empty')
        else if (size(layout%masses_by_type) < 1) then
            call st%fail('h5md: create: masses_by_type is empty')
        end if
        if (st%ok) then
            do k = 1, layout%dimension
                if (layout%periodic(k) .and. .not. layout%box_hi(k) > layout%box_lo(k)) &
                    call st%fail('h5md: create: a periodic box edge is not positive')
            end do
        end if
    end subroutine check_layout

    !> /h5md: version, author (the layout's, else $USER on rank 0), creator, and the units module
    !> when any unit is given.
    subroutine write_h5md_group(self, layout, st)
        class(h5md_writer_t), intent(inout) :: self
        type(h5md_layout_t), intent(in) :: layout
        type(h5_status_t), intent(inout) :: st
        integer(hid_t) :: g, gp, gu
        integer :: err
        character(len=256) :: who
        logical :: any_unit
        who = 'unknown'
        if (allocated(layout%author)) then
            if (len_trim(layout%author) > 0) who = layout%author
        else if (self%rank == 0) then
            call get_environment_variable('USER', who, status=err)
            if (err /= 0 .or. len_trim(who) == 0) who = 'unknown'
        end if
        call MPI_Bcast(who, len(who), MPI_CHARACTER, 0, self%comm)
        call h5gcreate_f(self%file, 'h5md', g, err); call st%check(err, 'create h5md')
        call h5_attr_int(st, g, 'version', [1, 1], scalar=.false.)
        call h5gcreate_f(g, 'author', gp, err); call st%check(err, 'create h5md/author')
        call h5_attr_text(st, gp, 'name', trim(who))
        call h5gclose_f(gp, err)
        call h5gcreate_f(g, 'creator', gp, err); call st%check(err, 'create h5md/creator')
        call h5_attr_text(st, gp, 'name', 'Terrace')
        call h5_attr_text(st, gp, 'version', trim(layout%creator_version))
        call h5gclose_f(gp, err)
        any_unit = len_trim(layout%unit_length) + len_trim(layout%unit_time) + len_trim(layout%unit_energy) + &
                   len_trim(layout%unit_velocity) + len_trim(layout%unit_mass) > 0
        if (any_unit) then
            call h5gcreate_f(g, 'modules', gp, err); call st%check(err, 'create h5md/modules')
            call h5gcreate_f(gp, 'units', gu, err); call st%check(err, 'create h5md/modules/units')
            call h5_attr_int(st, gu, 'version', [1, 0], scalar=.false.)
            call h5_attr_vltext(st, gu, 'system', 'SI')
            call h5gclose_f(gu, err); call h5gclose_f(gp, err)
        end if
        call h5gclose_f(g, err)
    end subroutine write_h5md_group

    !> particles/all/box (gp: particles/all): dimension, boundary, and box/edges, a time-dependent
    !> element whose step and time every other element shares.
    subroutine create_box(self, gp, layout, st)
        class(h5md_writer_t), intent(inout) :: self
        integer(hid_t), intent(in) :: gp
        type(h5md_layout_t), intent(in) :: layout
        type(h5_status_t), intent(inout) :: st
        integer(hid_t) :: gbox, gel
        integer :: err, k, D_
        character(len=8) :: boundary(3)
        D_ = layout%dimension
        call h5gcreate_f(gp, 'box', gbox, err); call st%check(err, 'create box')
        call h5_attr_int(st, gbox, 'dimension', [D_], scalar=.true.)
        do k = 1, D_
            boundary(k) = merge('periodic', 'none    ', layout%periodic(k))
        end do
        call h5_attr_text_list(st, gbox, 'boundary', boundary(1:D_))
        self%edges = layout%box_hi - layout%box_lo
        call h5gcreate_f(gbox, 'edges', gel, err); call st%check(err, 'create box/edges')
        call h5_make_series(st, gel, 'step', H5T_STD_I64LE, [integer(hsize_t) ::], [integer(hsize_t) ::], self%step)
        call h5_make_series(st, gel, 'time', H5T_IEEE_F64LE, [integer(hsize_t) ::], [integer(hsize_t) ::], self%time)
        call h5_attr_vltext(st, self%time, 'unit', trim(layout%unit_time))
        call h5_make_series(st, gel, 'value', H5T_IEEE_F64LE, [int(D_, hsize_t)], [int(D_, hsize_t)], self%edges_value, &
                         chunk_frames=chunk_scalar)
        call h5_attr_vltext(st, self%edges_value, 'unit', trim(layout%unit_length))
        call h5gclose_f(gel, err)
        call h5gclose_f(gbox, err)
    end subroutine create_box

    !> The time-dependent particle elements wanted (gp: particles/all): value [frames][N][D]
    !> (Fortran dims (D, N, frames)), step and time hard links to box/edges'. A chunk holds up to
    !> 1 MiB of one frame, or, when a frame is small, the frames of about 64 KiB (one chunk per frame
    !> of a seven-atom cluster would cost more in chunk index than in data).
    subroutine create_elements(self, gp, layout, st)
        class(h5md_writer_t), intent(inout) :: self
        integer(hid_t), intent(in) :: gp
        type(h5md_layout_t), intent(in) :: layout
        type(h5_status_t), intent(inout) :: st
        character(len=*), parameter :: shared = pgroup//'/box/edges'
        integer(hid_t) :: gel, dtype
        integer(hsize_t) :: nchunk, fchunk, natoms
        integer :: err, e, D_
        character(len=:), allocatable :: unit_force
        D_ = layout%dimension
        natoms = int(layout%natoms, hsize_t)
        nchunk = max(1_hsize_t, min(natoms, chunk_bytes/(8_hsize_t*D_)))
        fchunk = 1
        if (nchunk == natoms) fchunk = max(1_hsize_t, small_chunk_bytes/(8_hsize_t*D_*nchunk))
        unit_force = ''
        if (len_trim(layout%unit_energy) > 0 .and. len_trim(layout%unit_length) > 0) &
            unit_force = trim(layout%unit_energy)//' '//trim(layout%unit_length)//'-1'
        do e = 1, nel
            if (.not. self%want(e)) cycle
            call h5gcreate_f(gp, trim(el_name(e)), gel, err); call st%check(err, 'create '//trim(el_name(e)))
            dtype = merge(H5T_STD_I32LE, H5T_IEEE_F64LE, e == e_image)
            call h5_make_series(st, gel, 'value', dtype, [int(D_, hsize_t), natoms], [int(D_, hsize_t), nchunk], &
                                self%value(e), chunk_frames=fchunk)
            select case (e)
            case (e_pos); call h5_attr_vltext(st, self%value(e), 'unit', trim(layout%unit_length))
            case (e_vel); call h5_attr_vltext(st, self%value(e), 'unit', trim(layout%unit_velocity))
            case (e_force); call h5_attr_vltext(st, self%value(e), 'unit', unit_force)
            end select
            call h5lcreate_hard_f(self%file, shared//'/step', gel, 'step', err)
            call st%check(err, 'link '//trim(el_name(e))//'/step')
            call h5lcreate_hard_f(self%file, shared//'/time', gel, 'time', err)
            call st%check(err, 'link '//trim(el_name(e))//'/time')
            call h5gclose_f(gel, err)
        end do
    end subroutine create_elements

    !> What create and open_append do last: flush the file, then agree on every rank whether all
    !> went well; if not, the writer is released (closed) and msg says why.
    subroutine end_open(self, st, ok, msg)
        class(h5md_writer_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: err
        call h5_guard_begin('H5Fflush'); call h5fflush_f(self%file, H5F_SCOPE_GLOBAL_F, err); call h5_guard_end()
        call st%check(err, 'H5Fflush')
        self%last_flush = MPI_Wtime()
        self%opened = .true.
        call h5_agree(self%comm, st, ok, msg)
        if (.not. ok) call note_broken_hdf5_file()
        if (.not. ok) then
            call release(self)
            msg = 'h5md: '//trim(self%path)//': '//trim(msg)
        end if
    end subroutine end_open

    !> What create and open_append check first: ok (and msg '') unless the writer is open already.
    logical function already_open(self, what, ok, msg) result(is_open)
        class(h5md_writer_t), intent(in) :: self
        character(len=*), intent(in) :: what
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        is_open = self%opened
        ok = .not. is_open; msg = ''
        if (is_open) msg = 'h5md: '//what//': the writer is already open ('//self%path//')'
    end function already_open

    !> What create and open_append do before the file: the HDF5 library, the writer's own
    !> communicator (a duplicate of comm), its rank and size, the path.
    subroutine begin_open(self, path, comm, st)
        class(h5md_writer_t), intent(inout) :: self
        character(len=*), intent(in) :: path
        type(MPI_Comm), intent(in) :: comm
        type(h5_status_t), intent(inout) :: st
        call h5_library(st)
        if (.not. st%ok) return
        call MPI_Comm_dup(comm, self%comm)
        call MPI_Comm_rank(self%comm, self%rank)
        call MPI_Comm_size(self%comm, self%nprocs)
        self%path = trim(path)
    end subroutine begin_open

    !> Reopen an existing trajectory written by `create`/`write_frame` to append to it (a restart
    !> from a checkpoint): every time series (the particle elements and every observable) is cut
    !> back to its first `keep` entries, dropping what a run killed after its checkpoint may have
    !> written, and later frames are appended after them. Fails (ok = .false. on every rank) when
    !> the file cannot be opened, is not laid out as `create` lays it out, or holds fewer than
    !> `keep` frames. Collective.
    subroutine writer_open_append(self, path, comm, keep, ok, msg)
        class(h5md_writer_t), intent(inout) :: self
        character(len=*), intent(in) :: path
        type(MPI_Comm), intent(in) :: comm
        integer(i8), intent(in) :: keep
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(h5_status_t) :: st
        integer(hsize_t) :: nf
        character(len=256) :: text

        if (already_open(self, 'open_append', ok, msg)) return
        call begin_open(self, path, comm, st)
        if (.not. st%ok) then
            ok = .false.; msg = st%msg; return
        end if
        call h5_open_file(st, self%path, h5_append, self%file, self%comm, collective_metadata=.true., &
                          label=trim(self%path)//' (&output trajectory_file)')
        if (self%file < 0) then
            call MPI_Comm_free(self%comm)
            ok = .false.; msg = 'h5md: cannot open '//self%path//' to append to it'
            return
        end if
        self%opened = .true.
        call h5_transfer_list(st, .true., self%dxpl)
        call h5_transfer_list(st, .false., self%dxpl_rank0)

        call open_particle_data(self, st, nf)
        if (st%ok .and. int(nf, i8) < keep) then
            write (text, '(a,i0,a,i0)') 'the trajectory holds ', nf, ' frames, the checkpoint expects at least ', keep
            call st%fail(trim(text))
        end if
        self%nframes = int(keep, hsize_t)
        self%nflushed = self%nframes
        self%ndisk = self%nframes
        self%last_step = 0
        if (st%ok) call cut_back_frames(self, st, keep)
        call open_observables(self, st, keep)
        self%unit_time = ''
        self%masses_by_type = [0.0_dp]   ! only read at the first frame, which is written already
        call id_block(self%natoms, self%nprocs, self%rank, self%first, self%nmine)
        call set_block(self)
        call end_open(self, st, ok, msg)
    end subroutine writer_open_append

    !> The per-atom datasets (natoms) and the particle elements present (dimension; nf: the frames
    !> that every one of them, and the first one's step and time, holds), with that step and time.
    subroutine open_particle_data(self, st, nf)
        class(h5md_writer_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        integer(hsize_t), intent(out) :: nf
        integer(hsize_t) :: d3(3), m3(3), d1(1), m1(1)
        character(len=:), allocatable :: first_el
        logical :: exists
        integer :: err, e
        call h5dopen_f(self%file, pgroup//'/id', self%id, err); call st%check(err, 'open '//pgroup//'/id')
        call h5dopen_f(self%file, pgroup//'/species', self%species, err); call st%check(err, 'open species')
        call h5dopen_f(self%file, pgroup//'/mass', self%mass, err); call st%check(err, 'open mass')
        if (st%ok) then
            call h5_dataset_dims(st, self%id, d1, m1)
            self%natoms = int(d1(1), i8)
        end if
        first_el = ''
        nf = 0
        do e = 1, nel
            if (.not. st%ok) exit
            call h5lexists_f(self%file, pgroup//'/'//trim(el_name(e)), exists, err)
            self%want(e) = exists .and. err >= 0
            if (.not. self%want(e)) cycle
            call h5dopen_f(self%file, pgroup//'/'//trim(el_name(e))//'/value', self%value(e), err)
            call st%check(err, 'open '//trim(el_name(e))//'/value')
            call h5_dataset_dims(st, self%value(e), d3, m3)
            if (len(first_el) == 0) then
                first_el = pgroup//'/'//trim(el_name(e))
                self%dimension = int(d3(1))
                nf = d3(3)
                call h5dopen_f(self%file, first_el//'/step', self%step, err); call st%check(err, 'open step')
                call h5dopen_f(self%file, first_el//'/time', self%time, err); call st%check(err, 'open time')
            else
                ! (a job killed between two elements' writes of a frame leaves them one frame apart;
                ! frames past the checkpoint's are cut back anyway)
                nf = min(nf, d3(3))
            end if
        end do
        if (st%ok .and. len(first_el) > 0) then
            call h5_dataset_dims(st, self%step, d1, m1)
            nf = min(nf, d1(1))
            call h5_dataset_dims(st, self%time, d1, m1)
            nf = min(nf, d1(1))
        end if
        if (st%ok .and. len(first_el) == 0) call st%fail('no position, velocity, force or image element')
    end subroutine open_particle_data

    !> The particle elements, step, time and box/edges cut back to self%nframes = keep frames; the
    !> (fixed) edges and the last step read from the last row kept.
    subroutine cut_back_frames(self, st, keep)
        class(h5md_writer_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        integer(i8), intent(in) :: keep
        integer(i8), target :: step_t
        real(dp), target :: edges_t(3)
        integer :: err, e
        do e = 1, nel
            if (self%want(e)) call h5_extend(st, self%value(e), [int(self%dimension, hsize_t), &
                                                               int(self%natoms, hsize_t), self%nframes])
        end do
        call h5_extend(st, self%step, [self%nframes])
        call h5_extend(st, self%time, [self%nframes])
        ! box/edges: a time-dependent element (one row per frame) whose step and time the
        ! elements share; its rows are cut back too and the (fixed) edges read from row 0
        call h5dopen_f(self%file, pgroup//'/box/edges/value', self%edges_value, err)
        call st%check(err, 'open box/edges/value (a trajectory written by this version of Terrace)')
        if (st%ok) call h5_extend(st, self%edges_value, [int(self%dimension, hsize_t), self%nframes])
        edges_t = 0
        if (st%ok .and. keep > 0) call h5_read_slab(st, self%edges_value, H5T_NATIVE_DOUBLE, c_loc(edges_t), &
                                                 [0_hsize_t, 0_hsize_t], [int(self%dimension, hsize_t), 1_hsize_t], &
                                                 .true., self%dxpl)
        self%edges = edges_t
        if (st%ok .and. keep > 0) then
            call h5_read_slab(st, self%step, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(step_t), [self%nframes - 1], &
                           [1_hsize_t], .true., self%dxpl)
            self%last_step = step_t
        end if
    end subroutine cut_back_frames

    !> Every observable of the trajectory reopened, its value series cut back to `keep` entries
    !> (they are written with every frame: their step and time are box/edges', cut back already).
    subroutine open_observables(self, st, keep)
        class(h5md_writer_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        integer(i8), intent(in) :: keep
        integer(hid_t) :: g
        integer(hsize_t) :: d1(1), m1(1)
        integer :: err, k, nmembers, otype
        logical :: exists
        character(len=256) :: oname
        self%nobs = 0
        if (allocated(self%obs)) deallocate (self%obs)
        allocate (self%obs(4))
        call h5lexists_f(self%file, 'observables', exists, err)
        if (.not. (st%ok .and. exists)) return
        call h5gn_members_f(self%file, 'observables', nmembers, err); call st%check(err, 'list observables')
        call h5gopen_f(self%file, 'observables', g, err); call st%check(err, 'open observables')
        do k = 0, nmembers - 1
            if (.not. st%ok) exit
            call h5gget_obj_info_idx_f(self%file, 'observables', k, oname, otype, err)
            call st%check(err, 'observable name')
            if (self%nobs == size(self%obs)) call grow_obs(self)
            self%nobs = self%nobs + 1
            associate (o => self%obs(self%nobs))
                o%name = trim(oname)
                o%per_frame = .true.
                call h5dopen_f(g, o%name//'/value', o%value, err); call st%check(err, 'open '//o%name//'/value')
                if (st%ok) call h5_dataset_dims(st, o%value, d1, m1)
                if (st%ok .and. int(d1(1), i8) < keep) call st%fail('observable '//o%name//' holds too few entries')
                o%n = int(keep, hsize_t); o%ndisk = o%n
                if (st%ok) call h5_extend(st, o%value, [o%n])
            end associate
        end do
        call h5gclose_f(g, err)
    end subroutine open_observables

    subroutine grow_obs(w)
        class(h5md_writer_t), intent(inout) :: w
        type(observable_t), allocatable :: grown(:)
        allocate (grown(2*size(w%obs)))
        grown(1:w%nobs) = w%obs(1:w%nobs)
        call move_alloc(grown, w%obs)
    end subroutine grow_obs

    !> The box edges (hi - lo) of the frames written from now on (a box a barostat changes).
    subroutine writer_set_edges(self, edges)
        class(h5md_writer_t), intent(inout) :: self
        real(dp), intent(in) :: edges(3)
        self%edges = edges
    end subroutine writer_set_edges

    !> Append one frame. ids(1:nlocal) are the global ids (1..natoms) of this rank's atoms; over all
    !> ranks every id must appear exactly once. x, v, f, image are (>= dimension, >= nlocal) and
    !> needed only when the matching element was requested in create (pass them by keyword
    !> otherwise). Steps must not decrease. flush (default true) flushes the file after the frame
    !> (a caller that writes observables of the same sample flushes once after them).
    subroutine writer_write_frame(self, step, time, nlocal, ids, types, x, v, f, image, ok, msg, flush)
        class(h5md_writer_t), intent(inout), target :: self
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        integer, intent(in) :: nlocal
        integer(i8), intent(in) :: ids(:)
        integer, intent(in) :: types(:)
        real(dp), intent(in), optional :: x(:, :), v(:, :), f(:, :)
        integer, intent(in), optional :: image(:, :)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        logical, intent(in), optional :: flush
        type(h5_status_t) :: st
        type(frame_columns_t) :: cols
        integer :: nrecv
        integer(i8) :: total
        logical :: bad

        ok = .true.; msg = ''
        if (.not. self%opened) then
            ok = .false.; msg = 'h5md: write_frame: the writer is not open'; return
        end if
        ! ---- check the arguments on every rank, then agree
        call check_frame_args(self, st, nlocal, ids, types, x, v, f, image)
        if (self%nframes > 0 .and. step < self%last_step) call st%fail('h5md: write_frame: step decreases')
        total = merge(int(nlocal, i8), 0_i8, st%ok)
        if (self%nprocs > 1) call MPI_Allreduce(MPI_IN_PLACE, total, 1, MPI_INTEGER8, MPI_SUM, self%comm)
        if (self%nprocs > 1 .or. .not. st%ok) call h5_agree(self%comm, st, ok, msg)
        if (.not. ok) call note_broken_hdf5_file()
        if (.not. ok) return
        if (total /= self%natoms) then
            ok = .false.
            write (msg, '(a,i0,a,i0)') 'h5md: write_frame: the ranks hold ', total, ' atoms, expected ', self%natoms
            return
        end if

        cols = frame_columns(self)
        call send_to_owners(self, cols, nlocal, ids, types, x, v, f, image, nrecv)
        call place_received(self, nrecv, bad)
        if (bad) then
            ok = .false.; msg = 'h5md: write_frame: an atom id appears twice (or is missing) over the ranks'
            return
        end if
        call keep_frame(self, st, cols, nrecv, step, time)
        call flush_unless_told(self, st, flush)
        if (self%nprocs > 1 .or. .not. st%ok) call h5_agree(self%comm, st, ok, msg)
        if (.not. ok) call note_broken_hdf5_file()
        if (ok) then
            self%nframes = self%nframes + 1
            self%last_step = step
        else
            msg = 'h5md: write_frame: '//trim(msg)
        end if
    end subroutine writer_write_frame

    !> write_frame's arguments on this rank: the arrays the elements need, large enough; ids in
    !> 1..natoms and types in 1..size(masses_by_type).
    subroutine check_frame_args(self, st, nlocal, ids, types, x, v, f, image)
        class(h5md_writer_t), intent(in) :: self
        type(h5_status_t), intent(inout) :: st
        integer, intent(in) :: nlocal
        integer(i8), intent(in) :: ids(:)
        integer, intent(in) :: types(:)
        real(dp), intent(in), optional :: x(:, :), v(:, :), f(:, :)
        integer, intent(in), optional :: image(:, :)
        integer :: i, D_
        D_ = self%dimension
        if (nlocal < 0 .or. size(ids) < nlocal .or. size(types) < nlocal) &
            call st%fail('h5md: write_frame: nlocal exceeds the size of ids or types')
        call need_real(st, self%want(e_pos), x, 'x', D_, nlocal)
        call need_real(st, self%want(e_vel), v, 'v', D_, nlocal)
        call need_real(st, self%want(e_force), f, 'f', D_, nlocal)
        if (self%want(e_image)) then
            if (.not. present(image)) then
                call st%fail('h5md: write_frame: image is required (want_image)')
            else if (size(image, 1) < D_ .or. size(image, 2) < nlocal) then
                call st%fail('h5md: write_frame: image is too small')
            end if
        end if
        if (.not. st%ok) return
        do i = 1, nlocal
            if (ids(i) < 1 .or. ids(i) > self%natoms) then
                call st%fail('h5md: write_frame: atom id out of range 1..natoms'); exit
            end if
            if (types(i) < 1 .or. types(i) > size(self%masses_by_type)) then
                call st%fail('h5md: write_frame: atom type outside 1..size(masses_by_type)'); exit
            end if
        end do
    end subroutine check_frame_args

    subroutine need_real(st, wanted, a, what, D_, nlocal)
        type(h5_status_t), intent(inout) :: st
        logical, intent(in) :: wanted
        real(dp), intent(in), optional :: a(:, :)
        character(len=*), intent(in) :: what
        integer, intent(in) :: D_, nlocal
        if (.not. wanted) return
        if (.not. present(a)) then
            call st%fail('h5md: write_frame: '//what//' is required by the elements requested in create')
        else if (size(a, 1) < D_ .or. size(a, 2) < nlocal) then
            call st%fail('h5md: write_frame: '//what//' is too small')
        end if
    end subroutine need_real

    !> What one atom of a frame carries: reals (position, velocity, force: D each, element e from
    !> roff(e) + 1) and integers (id, the type at the first frame in row it, image in rows im+1..im+D).
    function frame_columns(self) result(c)
        class(h5md_writer_t), intent(in) :: self
        type(frame_columns_t) :: c
        integer :: e, D_
        D_ = self%dimension
        c%wr = 0; c%roff = 0
        do e = e_pos, e_force
            if (self%want(e)) then
                c%roff(e) = c%wr; c%wr = c%wr + D_
            end if
        end do
        c%it = merge(2, 0, self%nframes == 0)          ! row of the type in the integers (0: not sent)
        c%im = 1 + merge(1, 0, c%it > 0)                ! image: rows im+1 .. im+D
        c%wi = c%im + merge(D_, 0, self%want(e_image))
    end function frame_columns

    !> Every atom sent to the rank owning its id (block distribution of 1..natoms), into the work
    !> arrays rint, rreal (nrecv atoms received).
    subroutine send_to_owners(self, cols, nlocal, ids, types, x, v, f, image, nrecv)
        class(h5md_writer_t), intent(inout), target :: self
        type(frame_columns_t), intent(in) :: cols
        integer, intent(in) :: nlocal
        integer(i8), intent(in) :: ids(:)
        integer, intent(in) :: types(:)
        real(dp), intent(in), optional :: x(:, :), v(:, :), f(:, :)
        integer, intent(in), optional :: image(:, :)
        integer, intent(out) :: nrecv
        integer, allocatable :: scount(:), rcount(:), sdisp(:), rdisp(:), cursor(:)
        integer :: P, i, j, r, wr, wi, D_
        P = self%nprocs; D_ = self%dimension; wr = cols%wr; wi = cols%wi
        associate (w => self%work)
            if (P == 1) then
                ! one rank: the atoms are its own block already (no exchange)
                nrecv = nlocal
                call reserve_recv(w, max(wr, 1), wi, D_, max(nrecv, int(self%nmine)))
                do i = 1, nlocal
                    call pack(i, w%rint(:, i), w%rreal(:, i))
                end do
            else
                allocate (scount(0:P - 1), rcount(0:P - 1), sdisp(0:P - 1), rdisp(0:P - 1), cursor(0:P - 1))
                call reserve_send(w, max(wr, 1), wi, nlocal)
                call exchange_plan(ids(1:nlocal), self%natoms, self%comm, w%dest(1:nlocal), scount, sdisp, rcount, rdisp)
                cursor = sdisp
                do i = 1, nlocal
                    r = w%dest(i)
                    cursor(r) = cursor(r) + 1; j = cursor(r)
                    call pack(i, w%sint(:, j), w%sreal(:, j))
                end do
                nrecv = sum(rcount)
                call reserve_recv(w, max(wr, 1), wi, D_, max(nrecv, int(self%nmine)))
                call MPI_Alltoallv(w%sint, wi*scount, wi*sdisp, MPI_INTEGER8, w%rint, wi*rcount, wi*rdisp, &
                                   MPI_INTEGER8, self%comm)
                if (wr > 0) call MPI_Alltoallv(w%sreal, wr*scount, wr*sdisp, MPI_DOUBLE_PRECISION, w%rreal, wr*rcount, &
                                               wr*rdisp, MPI_DOUBLE_PRECISION, self%comm)
            end if
        end associate

    contains

        !> Atom i's id, type (first frame), image and reals into one column of the integers and reals.
        subroutine pack(i, ints, reals)
            integer, intent(in) :: i
            integer(i8), intent(out) :: ints(:)
            real(dp), intent(out) :: reals(:)
            ints(1) = ids(i)
            if (cols%it > 0) ints(cols%it) = types(i)
            if (self%want(e_image)) ints(cols%im + 1:cols%im + D_) = image(1:D_, i)
            if (self%want(e_pos)) reals(cols%roff(e_pos) + 1:cols%roff(e_pos) + D_) = x(1:D_, i)
            if (self%want(e_vel)) reals(cols%roff(e_vel) + 1:cols%roff(e_vel) + D_) = v(1:D_, i)
            if (self%want(e_force)) reals(cols%roff(e_force) + 1:cols%roff(e_force) + D_) = f(1:D_, i)
        end subroutine pack

    end subroutine send_to_owners

    !> The row of each received atom in this rank's block (id order), every id exactly once (bad,
    !> the same on every rank, when not).
    subroutine place_received(self, nrecv, bad)
        class(h5md_writer_t), intent(inout), target :: self
        integer, intent(in) :: nrecv
        logical, intent(out) :: bad
        integer(i8) :: kk
        integer :: j
        associate (row => self%work%row, seen => self%work%seen, rint => self%work%rint)
            seen = .false.
            bad = nrecv /= self%nmine
            if (.not. bad) then
                do j = 1, nrecv
                    kk = rint(1, j) - self%first + 1
                    if (kk < 1 .or. kk > self%nmine) then
                        bad = .true.; exit
                    end if
                    if (seen(kk)) then
                        bad = .true.; exit
                    end if
                    seen(kk) = .true.; row(j) = int(kk)
                end do
            end if
        end associate
        if (self%nprocs > 1) call MPI_Allreduce(MPI_IN_PLACE, bad, 1, MPI_LOGICAL, MPI_LOR, self%comm)
    end subroutine place_received

    !> The frame kept in memory (slot nbuf + 1; a full block goes to the file first); at the first
    !> frame, this rank's block of ids, species and masses written.
    subroutine keep_frame(self, st, cols, nrecv, step, time)
        class(h5md_writer_t), intent(inout), target :: self
        type(h5_status_t), intent(inout) :: st
        type(frame_columns_t), intent(in) :: cols
        integer, intent(in) :: nrecv
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time
        integer :: j, k, e, D_
        D_ = self%dimension
        associate (row => self%work%row, rint => self%work%rint, rreal => self%work%rreal)
            if (self%nbuf >= self%block) call write_block(self, st)
            k = self%nbuf + 1
            do e = e_pos, e_force
                if (.not. self%want(e)) cycle
                do j = 1, nrecv
                    self%breal(1:D_, row(j), k, e) = rreal(cols%roff(e) + 1:cols%roff(e) + D_, j)
                end do
            end do
            if (self%want(e_image)) then
                do j = 1, nrecv
                    self%bimage(1:D_, row(j), k) = int(rint(cols%im + 1:cols%im + D_, j))
                end do
            end if
            self%bstep(k) = step; self%btime(k) = time; self%bedges(1:D_, k) = self%edges(1:D_)
        end associate
        if (self%nframes == 0) call write_atom_constants(self, st, cols, nrecv)
        if (st%ok) self%nbuf = k
    end subroutine keep_frame

    !> id, species and mass of this rank's block of ids (at the first frame: the types are sent
    !> with it only).
    subroutine write_atom_constants(self, st, cols, nrecv)
        class(h5md_writer_t), intent(inout), target :: self
        type(h5_status_t), intent(inout) :: st
        type(frame_columns_t), intent(in) :: cols
        integer, intent(in) :: nrecv
        real(dp), allocatable, target :: mbuf(:)
        integer, allocatable, target :: tbuf(:)
        integer(i8), allocatable, target :: idbuf(:)
        integer :: j
        associate (row => self%work%row, rint => self%work%rint, nm => int(self%nmine, hsize_t), &
                   f0 => int(self%first - 1, hsize_t))
            allocate (idbuf(max(self%nmine, 1_i8)), tbuf(max(self%nmine, 1_i8)), mbuf(max(self%nmine, 1_i8)))
            do j = 1, nrecv
                idbuf(row(j)) = rint(1, j)
                tbuf(row(j)) = int(rint(cols%it, j))
                mbuf(row(j)) = self%masses_by_type(tbuf(row(j)))
            end do
            call h5_write_slab(st, self%id, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(idbuf), [f0], [nm], &
                               nm > 0, self%dxpl)
            call h5_write_slab(st, self%species, H5T_NATIVE_INTEGER, c_loc(tbuf), [f0], [nm], nm > 0, self%dxpl)
            call h5_write_slab(st, self%mass, H5T_NATIVE_DOUBLE, c_loc(mbuf), [f0], [nm], nm > 0, self%dxpl)
        end associate
    end subroutine write_atom_constants

    !> Send arrays for n atoms (wr reals, wi integers each), grown with 25 % headroom when too small
    !> (the number of atoms a rank owns drifts a little from frame to frame).
    subroutine reserve_send(w, wr, wi, n)
        type(frame_work_t), intent(inout) :: w
        integer, intent(in) :: wr, wi, n
        integer :: cap
        if (allocated(w%sint)) then
            if (n <= w%send_capacity .and. size(w%sreal, 1) == wr .and. size(w%sint, 1) == wi) return
            deallocate (w%dest, w%sint, w%sreal)
        end if
        cap = max(1, n + n/4)
        allocate (w%dest(cap), w%sint(wi, cap), w%sreal(wr, cap))
        w%send_capacity = cap
    end subroutine reserve_send

    !> Receive arrays and this rank's block buffers for n atoms (n >= the block size).
    subroutine reserve_recv(w, wr, wi, D, n)
        type(frame_work_t), intent(inout) :: w
        integer, intent(in) :: wr, wi, D, n
        integer :: cap
        if (allocated(w%rint)) then
            if (n <= w%recv_capacity .and. size(w%rreal, 1) == wr .and. size(w%rint, 1) == wi) return
            deallocate (w%row, w%seen, w%rint, w%rreal, w%rbuf, w%ibuf)
        end if
        cap = max(1, n)
        allocate (w%row(cap), w%seen(cap), w%rint(wi, cap), w%rreal(wr, cap), w%rbuf(D, cap), w%ibuf(D, cap))
        w%recv_capacity = cap
    end subroutine reserve_recv

    !> Append (step, time, value) to observables/<name> (created at its first call, with the
    !> optional unit). Collective; rank 0's values are written. flush (default true) flushes the file.
    !> per_frame (fixed at the first call): the observable is written once with every frame, just
    !> after it (same step), and its step and time are hard links to the frames' (box/edges/step,
    !> time), so that only its value grows.
    subroutine writer_write_observable(self, name, step, time, value, ok, msg, unit, flush, per_frame)
        class(h5md_writer_t), intent(inout), target :: self
        character(len=*), intent(in) :: name
        integer(i8), intent(in) :: step
        real(dp), intent(in) :: time, value
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=*), intent(in), optional :: unit
        logical, intent(in), optional :: flush, per_frame
        type(h5_status_t) :: st
        type(observable_t), allocatable :: grown(:)
        integer :: k, i, err
        integer(hid_t) :: g, go
        integer(i8), target :: step_t
        real(dp), target :: time_t, value_t

        ok = .true.; msg = ''
        if (.not. self%opened) then
            ok = .false.; msg = 'h5md: write_observable: the writer is not open'; return
        end if
        if (len_trim(name) == 0 .or. index(name, '/') > 0 .or. index(name, '.') == 1) then
            ok = .false.; msg = 'h5md: write_observable: bad observable name "'//trim(name)//'"'; return
        end if
        k = 0
        do i = 1, self%nobs
            if (self%obs(i)%name == trim(name)) k = i
        end do
        if (k == 0) then
            if (self%nobs == size(self%obs)) then
                allocate (grown(2*size(self%obs)))
                grown(1:self%nobs) = self%obs(1:self%nobs)
                call move_alloc(grown, self%obs)
            end if
            self%nobs = self%nobs + 1; k = self%nobs
            associate (o => self%obs(k))
                o%name = trim(name); o%n = 0; o%ndisk = 0
                o%per_frame = .false.
                if (present(per_frame)) o%per_frame = per_frame
                call h5_group(st, self%file, 'observables', g)
                call h5gcreate_f(g, o%name, go, err); call st%check(err, 'create observables/'//o%name)
                if (o%per_frame) then
                    call h5lcreate_hard_f(self%file, pgroup//'/box/edges/step', go, 'step', err)
                    call st%check(err, 'link observables/'//o%name//'/step')
                    call h5lcreate_hard_f(self%file, pgroup//'/box/edges/time', go, 'time', err)
                    call st%check(err, 'link observables/'//o%name//'/time')
                else
                    call h5_make_series(st, go, 'step', H5T_STD_I64LE, [integer(hsize_t) ::], [integer(hsize_t) ::], &
                                     o%step)
                    call h5_make_series(st, go, 'time', H5T_IEEE_F64LE, [integer(hsize_t) ::], [integer(hsize_t) ::], &
                                     o%time)
                    call h5_attr_vltext(st, o%time, 'unit', self%unit_time)
                end if
                call h5_make_series(st, go, 'value', H5T_IEEE_F64LE, [integer(hsize_t) ::], [integer(hsize_t) ::], &
                                 o%value)
                if (present(unit)) call h5_attr_vltext(st, o%value, 'unit', unit)
                call h5gclose_f(go, err); call h5gclose_f(g, err)
            end associate
        end if
        associate (o => self%obs(k))
            step_t = step; time_t = time; value_t = value
            if (o%per_frame) then
                if (o%n + 1 /= self%nframes .or. step /= self%last_step) &
                    call st%fail('a per-frame observable must be written once after each frame, at its step')
            else
                call h5_extend(st, o%step, [o%n + 1])
                call h5_extend(st, o%time, [o%n + 1])
                call h5_write_slab(st, o%step, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(step_t), [o%n], [1_hsize_t], &
                                self%rank == 0, self%dxpl_rank0)
                call h5_write_slab(st, o%time, H5T_NATIVE_DOUBLE, c_loc(time_t), [o%n], [1_hsize_t], self%rank == 0, &
                                self%dxpl_rank0)
            end if
            if (o%per_frame) then
                ! kept with the frames in memory, written with their block
                if (.not. allocated(o%buf)) allocate (o%buf(self%block + 1))
                if (int(o%n - o%ndisk) >= size(o%buf)) call grow_values(o%buf)
                o%buf(o%n - o%ndisk + 1) = value
            else
                call h5_extend(st, o%value, [o%n + 1])
                call h5_write_slab(st, o%value, H5T_NATIVE_DOUBLE, c_loc(value_t), [o%n], [1_hsize_t], self%rank == 0, &
                                self%dxpl_rank0)
                o%ndisk = o%n + 1
            end if
        end associate
        call flush_unless_told(self, st, flush)
        call h5_agree(self%comm, st, ok, msg)
        if (.not. ok) call note_broken_hdf5_file()
        if (ok) then
            self%obs(k)%n = self%obs(k)%n + 1
        else
            msg = 'h5md: write_observable '//trim(name)//': '//trim(msg)
        end if
    end subroutine writer_write_observable

    !> The per-frame observables of the frame just written (write_observable with per_frame and
    !> flush = .false. for each name, in one call): values(k) is observables/names(k) (trailing blanks
    !> ignored). The same names in the same order at every frame find their series without a search.
    !> Collective; rank 0's values are written.
    subroutine writer_write_frame_observables(self, names, values, ok, msg)
        class(h5md_writer_t), intent(inout), target :: self
        character(len=*), intent(in) :: names(:)
        real(dp), intent(in) :: values(:)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(h5_status_t) :: st
        integer :: k, i, j
        logical :: known
        ok = .true.; msg = ''
        if (.not. self%opened) then
            ok = .false.; msg = 'h5md: write_frame_observables: the writer is not open'; return
        end if
        if (size(values) /= size(names)) then
            ok = .false.; msg = 'h5md: write_frame_observables: as many values as names are needed'; return
        end if
        if (allocated(self%frame_obs)) then
            if (size(self%frame_obs) /= size(names)) deallocate (self%frame_obs)
        end if
        if (.not. allocated(self%frame_obs)) allocate (self%frame_obs(size(names)), source=0)
        do k = 1, size(names)
            j = self%frame_obs(k)
            known = j >= 1 .and. j <= self%nobs
            if (known) known = self%obs(j)%per_frame .and. self%obs(j)%name == names(k)
            if (.not. known) then
                ! first sight of this name here (created, or found, by write_observable)
                call self%write_observable(names(k), self%last_step, 0.0_dp, values(k), ok, msg, flush=.false., &
                                           per_frame=.true.)
                if (.not. ok) return
                do i = 1, self%nobs
                    if (self%obs(i)%name == trim(names(k))) self%frame_obs(k) = i
                end do
                cycle
            end if
            associate (o => self%obs(j))
                if (o%n + 1 /= self%nframes) then
                    call st%fail('a per-frame observable must be written once after each frame, at its step')
                    exit
                end if
                if (.not. allocated(o%buf)) allocate (o%buf(self%block + 1))
                if (int(o%n - o%ndisk) >= size(o%buf)) call grow_values(o%buf)
                o%buf(o%n - o%ndisk + 1) = values(k)
                o%n = o%n + 1
            end associate
        end do
        if (self%nprocs > 1 .or. .not. st%ok) then
            call h5_agree(self%comm, st, ok, msg)
            if (.not. ok) msg = 'h5md: write_frame_observables: '//trim(msg)
        end if
    end subroutine writer_write_frame_observables

    !> Flush the file after a frame or an observable unless the caller said flush = .false.
    subroutine flush_unless_told(self, st, flush)
        class(h5md_writer_t), intent(inout), target :: self
        type(h5_status_t), intent(inout) :: st
        logical, intent(in), optional :: flush
        integer :: err
        if (present(flush)) then
            if (.not. flush) return
        end if
        call write_block(self, st)
        call h5_guard_begin('H5Fflush'); call h5fflush_f(self%file, H5F_SCOPE_GLOBAL_F, err); call h5_guard_end()
        call st%check(err, 'H5Fflush')
        self%nflushed = self%nframes
    end subroutine flush_unless_told

    !> The frames kept in memory (and the per-frame observables' values) into the file: each series
    !> extended once and written as one hyperslab. Collective (every rank keeps the same frames).
    subroutine write_block(self, st)
        class(h5md_writer_t), intent(inout), target :: self
        type(h5_status_t), intent(inout) :: st
        integer(hsize_t) :: nb, Dh, nd
        integer :: e, k
        if (self%nbuf > 0) then
            nb = int(self%nbuf, hsize_t); Dh = int(self%dimension, hsize_t); nd = self%ndisk
            associate (nm => int(self%nmine, hsize_t), f0 => int(self%first - 1, hsize_t))
                do e = 1, nel
                    if (.not. self%want(e)) cycle
                    call h5_extend(st, self%value(e), [Dh, int(self%natoms, hsize_t), nd + nb])
                    if (e == e_image) then
                        call h5_write_slab(st, self%value(e), H5T_NATIVE_INTEGER, c_loc(self%bimage), [0_hsize_t, f0, nd], &
                                           [Dh, nm, nb], nm > 0, self%dxpl)
                    else
                        call h5_write_slab(st, self%value(e), H5T_NATIVE_DOUBLE, c_loc(self%breal(1, 1, 1, e)), &
                                           [0_hsize_t, f0, nd], [Dh, nm, nb], nm > 0, self%dxpl)
                    end if
                end do
            end associate
            call h5_extend(st, self%step, [nd + nb])
            call h5_extend(st, self%time, [nd + nb])
            call h5_extend(st, self%edges_value, [Dh, nd + nb])
            call h5_write_slab(st, self%step, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(self%bstep), [nd], [nb], &
                               self%rank == 0, self%dxpl_rank0)
            call h5_write_slab(st, self%time, H5T_NATIVE_DOUBLE, c_loc(self%btime), [nd], [nb], self%rank == 0, &
                               self%dxpl_rank0)
            call h5_write_slab(st, self%edges_value, H5T_NATIVE_DOUBLE, c_loc(self%bedges), [0_hsize_t, nd], [Dh, nb], &
                               self%rank == 0, self%dxpl_rank0)
            self%ndisk = nd + nb
            self%nbuf = 0
        end if
        do k = 1, self%nobs
            associate (o => self%obs(k))
                if (.not. o%per_frame .or. o%n == o%ndisk) cycle
                call h5_extend(st, o%value, [o%n])
                call h5_write_slab(st, o%value, H5T_NATIVE_DOUBLE, c_loc(o%buf), [o%ndisk], [o%n - o%ndisk], &
                                   self%rank == 0, self%dxpl_rank0)
                o%ndisk = o%n
            end associate
        end do
    end subroutine write_block

    !> The number of frames kept in memory before they go into the file (the same on every rank:
    !> from the global frame size), and the buffers for them.
    subroutine set_block(self)
        class(h5md_writer_t), intent(inout) :: self
        integer(i8) :: bytes
        integer :: D_, nm
        D_ = self%dimension
        bytes = self%natoms*D_*(8*count(self%want(e_pos:e_force)) + merge(4, 0, self%want(e_image)))
        self%block = int(max(1_i8, min(int(max_block_frames, i8), block_bytes/max(bytes, 1_i8))))
        self%nbuf = 0
        nm = int(max(self%nmine, 1_i8))
        if (allocated(self%breal)) deallocate (self%breal, self%bimage, self%bstep, self%btime, self%bedges)
        allocate (self%breal(D_, nm, self%block, e_pos:e_force), self%bimage(D_, nm, self%block), &
                  self%bstep(self%block), self%btime(self%block), self%bedges(D_, self%block))
    end subroutine set_block

    !> Whether the next write_frame goes to the file (its block is full, or it is the first frame:
    !> ids, species and masses), rather than only into memory. The same on every rank.
    logical function writer_frame_touches_file(self)
        class(h5md_writer_t), intent(in) :: self
        writer_frame_touches_file = self%opened .and. (self%nbuf >= self%block .or. self%nframes == 0)
    end function writer_frame_touches_file

    !> Whether at least min_interval seconds of wall time have passed since the last flush (rank 0's
    !> clock decides for every rank). Collective.
    logical function writer_flush_due(self, min_interval) result(due)
        class(h5md_writer_t), intent(inout) :: self
        real(dp), intent(in) :: min_interval
        due = .false.
        if (.not. self%opened) return
        if (self%rank == 0) due = MPI_Wtime() - self%last_flush >= min_interval
        if (self%nprocs > 1) call MPI_Bcast(due, 1, MPI_LOGICAL, 0, self%comm)
    end function writer_flush_due

    !> values grown to twice their size, kept
    subroutine grow_values(values)
        real(dp), allocatable, intent(inout) :: values(:)
        real(dp), allocatable :: grown(:)
        allocate (grown(2*size(values)))
        grown(1:size(values)) = values
        call move_alloc(grown, values)
    end subroutine grow_values

    !> Flush the file to disk (collective).
    !> With min_interval (seconds of wall time), only when at least that long has passed since the
    !> last flush of this writer (rank 0's clock decides for every rank). A flush writes HDF5's
    !> metadata (every extended dataset's header) and syncs the file: for a small system it costs
    !> several times a frame's data, so frequent small frames are flushed in batches.
    subroutine writer_flush(self, ok, msg, min_interval)
        class(h5md_writer_t), intent(inout), target :: self
        logical, intent(out), optional :: ok
        character(len=*), intent(out), optional :: msg
        real(dp), intent(in), optional :: min_interval
        type(h5_status_t) :: st
        integer :: err
        logical :: ok_, due
        character(len=256) :: msg_
        ok_ = .true.; msg_ = ''
        if (self%opened) then
            due = .true.
            if (present(min_interval)) due = self%flush_due(min_interval)
            if (due) then
                call write_block(self, st)
                call h5_guard_begin('H5Fflush'); call h5fflush_f(self%file, H5F_SCOPE_GLOBAL_F, err); call h5_guard_end()
                call st%check(err, 'H5Fflush')
                call h5_agree(self%comm, st, ok_, msg_)
                if (.not. ok_) call note_broken_hdf5_file()
                self%last_flush = MPI_Wtime()
                if (ok_) self%nflushed = self%nframes
            end if
        end if
        if (present(ok)) ok = ok_
        if (present(msg)) msg = msg_
    end subroutine writer_flush

    !> Close the file (collective). Closing a writer that is not open does nothing.
    subroutine writer_close(self, ok, msg)
        class(h5md_writer_t), intent(inout), target :: self
        logical, intent(out), optional :: ok
        character(len=*), intent(out), optional :: msg
        type(h5_status_t) :: st
        integer :: err
        logical :: ok_
        character(len=256) :: msg_
        ok_ = .true.; msg_ = ''
        if (self%opened) then
            call write_block(self, st)
            call h5_guard_begin('H5Fflush'); call h5fflush_f(self%file, H5F_SCOPE_GLOBAL_F, err); call h5_guard_end()
            call st%check(err, 'H5Fflush')
            call h5_agree(self%comm, st, ok_, msg_)
            if (.not. ok_) call note_broken_hdf5_file()
            call release(self)
        end if
        if (present(ok)) ok = ok_
        if (present(msg)) msg = msg_
    end subroutine writer_close

    logical function writer_is_open(self)
        class(h5md_writer_t), intent(in) :: self
        writer_is_open = self%opened
    end function writer_is_open

    integer(i8) function writer_frames_written(self)
        class(h5md_writer_t), intent(in) :: self
        writer_frames_written = int(self%nframes, i8)
    end function writer_frames_written

    !> Frames on disk: written and flushed (by write_frame, flush or write_observable).
    integer(i8) function writer_frames_flushed(self)
        class(h5md_writer_t), intent(in) :: self
        writer_frames_flushed = int(self%nflushed, i8)
    end function writer_frames_flushed

    !> The times of the frames written so far (every rank reads them; collective).
    subroutine writer_frame_times(self, times, ok, msg)
        class(h5md_writer_t), intent(inout), target :: self
        real(dp), allocatable, target, intent(out) :: times(:)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(h5_status_t) :: st
        allocate (times(self%nframes))
        ok = .true.; msg = ''
        if (.not. self%opened) then
            ok = .false.; msg = 'h5md: frame_times: the writer is not open'; return
        end if
        call write_block(self, st)
        if (self%nframes > 0) call h5_read_slab(st, self%time, H5T_NATIVE_DOUBLE, c_loc(times), [0_hsize_t], &
                                                [self%nframes], .true., self%dxpl)
        call h5_agree(self%comm, st, ok, msg)
        if (.not. ok) msg = 'h5md: frame_times: '//trim(msg)
    end subroutine writer_frame_times

    !> Time-independent tuples of particles, written once (H5MD 1.1, proposals 101 and 103):
    !> /connectivity/<name> holds tuples(:, k) as particle ids (int64, [M][T] in C order), with the
    !> attribute particles_group = 'all' (particles/all has an id element, so the values are ids);
    !> /parameters/terrace/<name>_index holds the same tuples as 0-based rows of the id-ordered
    !> particle arrays (id - 1, int32), the indexing an XDMF Topology reads. Collective; rank 0's
    !> tuples are written (every rank must pass the same shape).
    subroutine writer_write_connectivity(self, name, tuples, ok, msg)
        class(h5md_writer_t), intent(inout) :: self
        character(len=*), intent(in) :: name
        integer(i8), intent(in), target, contiguous :: tuples(:, :)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(h5_status_t) :: st
        integer(hid_t) :: g, gp, d
        integer :: err
        integer(hsize_t) :: dims(2)
        integer, allocatable, target :: rows(:, :)
        ok = .true.; msg = ''
        if (.not. self%opened) then
            ok = .false.; msg = 'h5md: write_connectivity: the writer is not open'; return
        end if
        if (len_trim(name) == 0 .or. index(name, '/') > 0) then
            ok = .false.; msg = 'h5md: write_connectivity: bad name "'//trim(name)//'"'; return
        end if
        if (size(tuples) > 0) then
            if (minval(tuples) < 1 .or. maxval(tuples) > self%natoms) &
                call st%fail('a tuple names a particle id outside 1..N')
        end if
        dims = [int(size(tuples, 1), hsize_t), int(size(tuples, 2), hsize_t)]
        call h5_group(st, self%file, 'connectivity', g)
        call h5_make_fixed(st, g, trim(name), H5T_STD_I64LE, dims, d)
        call h5_attr_text(st, d, 'particles_group', 'all')
        call h5_write_slab(st, d, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(tuples), [0_hsize_t, 0_hsize_t], dims, &
                           self%rank == 0 .and. size(tuples) > 0, self%dxpl_rank0)
        call h5dclose_f(d, err)
        call h5gclose_f(g, err)
        allocate (rows(size(tuples, 1), size(tuples, 2)))
        rows = int(tuples - 1)
        call h5_group(st, self%file, 'parameters', g)
        call h5_group(st, g, 'terrace', gp)
        call h5_make_fixed(st, gp, trim(name)//'_index', H5T_STD_I32LE, dims, d)
        call h5_write_slab(st, d, H5T_NATIVE_INTEGER, c_loc(rows), [0_hsize_t, 0_hsize_t], dims, &
                           self%rank == 0 .and. size(tuples) > 0, self%dxpl_rank0)
        call h5dclose_f(d, err)
        call h5gclose_f(gp, err)
        call h5gclose_f(g, err)
        call h5_guard_begin('H5Fflush'); call h5fflush_f(self%file, H5F_SCOPE_GLOBAL_F, err); call h5_guard_end()
        call st%check(err, 'H5Fflush')
        call h5_agree(self%comm, st, ok, msg)
        if (.not. ok) call note_broken_hdf5_file()
        if (.not. ok) msg = 'h5md: write_connectivity '//trim(name)//': '//trim(msg)
    end subroutine writer_write_connectivity

    !> Close every HDF5 object of the writer and the file; free the communicator.
    subroutine release(self)
        class(h5md_writer_t), intent(inout) :: self
        integer :: err, e, k
        do e = 1, nel
            if (self%value(e) >= 0) call h5dclose_f(self%value(e), err)
            self%value(e) = -1
        end do
        do k = 1, self%nobs
            if (self%obs(k)%step >= 0) call h5dclose_f(self%obs(k)%step, err)
            if (self%obs(k)%time >= 0) call h5dclose_f(self%obs(k)%time, err)
            if (self%obs(k)%value >= 0) call h5dclose_f(self%obs(k)%value, err)
        end do
        if (allocated(self%obs)) deallocate (self%obs)
        if (allocated(self%frame_obs)) deallocate (self%frame_obs)
        self%nobs = 0
        self%work = frame_work_t()
        self%nbuf = 0
        if (self%step >= 0) call h5dclose_f(self%step, err)
        if (self%time >= 0) call h5dclose_f(self%time, err)
        if (self%id >= 0) call h5dclose_f(self%id, err)
        if (self%species >= 0) call h5dclose_f(self%species, err)
        if (self%mass >= 0) call h5dclose_f(self%mass, err)
        if (self%edges_value >= 0) call h5dclose_f(self%edges_value, err)
        self%step = -1; self%time = -1; self%id = -1; self%species = -1; self%mass = -1; self%edges_value = -1
        if (self%dxpl >= 0) call h5pclose_f(self%dxpl, err)
        if (self%dxpl_rank0 >= 0) call h5pclose_f(self%dxpl_rank0, err)
        self%dxpl = -1; self%dxpl_rank0 = -1
        if (self%file >= 0) then
            call h5_guard_begin('H5Fclose'); call h5fclose_f(self%file, err); call h5_guard_end()
            call h5_writer_closed()
        end if
        self%file = -1
        if (self%opened) call MPI_Comm_free(self%comm)
        self%opened = .false.
    end subroutine release

end module terrace_h5md
