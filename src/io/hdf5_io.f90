!> The one HDF5 layer under Terrace's files: the H5MD writer (h5md.f90), the H5MD reader
!> (h5md_reader.f90) and the checkpoints (checkpoint.f90) call HDF5 through these procedures.
!>
!> Errors: a sequence of calls shares one h5_status_t; the first failure is kept (`HDF5 error in
!> <what>` or the caller's own text) and later calls still run and fail harmlessly, so that every
!> rank makes the same collective calls. h5_agree turns the statuses of all ranks of a communicator
!> into the same ok on every rank (the message of the lowest failing rank). HDF5's own error
!> printing is switched off once, by h5_library.
!>
!> Shapes are Fortran's (the reverse of C / h5py): a dataset Float[frames][N][D] has Fortran dims
!> (D, N, frames). Hyperslab starts are 0-based. Files are opened either through MPI-IO (a
!> communicator given: every procedure on that file is then collective) or with the default POSIX
!> driver (each process alone: the readers).
module terrace_hdf5_io
    use, intrinsic :: iso_c_binding, only: c_ptr, c_loc, c_char, c_null_char, c_f_pointer, c_associated
    use, intrinsic :: iso_fortran_env, only: int32
    use terrace_kinds, only: dp, i8
    use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_Bcast, MPI_IN_PLACE, &
                       MPI_INTEGER, MPI_MIN, MPI_CHARACTER, MPI_INFO_NULL, MPI_COMM_WORLD, MPI_Barrier
    use terrace_signals, only: watchdog_arm, watchdog_disarm, test_stall
    use terrace_file_ops, only: clear_mpiio_semaphore
    use hdf5
    implicit none
    private

    !> Error state of a sequence of HDF5 calls.
    type, public :: h5_status_t
        logical :: ok = .true.
        character(len=1024) :: msg = ''
    contains
        procedure :: check => status_check
        procedure :: fail => status_fail
    end type h5_status_t

    integer, parameter, public :: h5_create = 1, h5_read = 2, h5_append = 3   !< h5_open_file modes

    public :: h5_library, h5_agree, h5_open_file, h5_transfer_list, h5_writer_closed, h5_guard_begin, h5_guard_end, &
              h5_watch_begin, h5_watch_end, h5_section_begin, h5_section_end
    public :: h5_make_fixed, h5_make_series, h5_extend, h5_dataset_rank, h5_dataset_dims
    public :: h5_write_slab, h5_read_slab, h5_read_whole, h5_read_at
    public :: h5_attr_int, h5_attr_scalar, h5_attr_text, h5_attr_text_list, h5_attr_vltext
    public :: h5_read_attr_scalar, h5_read_attr_strings, h5_read_attr_string
    public :: h5_link_exists, h5_group

    integer(hsize_t), parameter :: chunk_scalar = 512      !< default chunk of a series of scalars

    !> The I/O watchdog (terrace_signals: an alarm that prints one prepared line and ends the
    !> process), for HDF5 calls that may never return:
    !>  - Collective sections (h5_section_begin/h5_section_end): every rank arms the watchdog when
    !>    it enters an operation on a file open for parallel writing (a trajectory frame with its
    !>    observables, a flush, a close, a checkpoint) and disarms it only after a barrier over
    !>    the file's communicator at the end, so while any rank is stuck inside (a failed write
    !>    that left the ranks in different collectives: HDF5 1.10 on a full device skips the
    !>    MPI_File_sync the others wait in; a file system that does not answer), every other rank
    !>    stays armed too, waiting in HDF5's collectives or in that barrier.
    !>  - Opening a file to read (h5_watch_begin/h5_watch_end; each process alone): HDF5 1.10
    !>    spins forever on some damaged files.
    !>  - Outside a section, a failed call while a file is open for parallel writing (status_check)
    !>    and every flush and close of such a file (h5_guard_begin/h5_guard_end) arm it too.
    !> One line for the job, whichever rank is stuck (arm_on_rank): rank r of MPI_COMM_WORLD fires
    !> after limit + r*watchdog_grace_s seconds, so rank 0 prints when it is armed and can run;
    !> otherwise (not armed, or its process cannot run at all) the lowest armed rank that can
    !> prints one grace later (rank r after r graces), and the launcher ends
    !> the others when it exits (mpirun does within a second); every armed rank also ends by its
    !> own alarm, so none hangs. Ranks from watchdog_quiet_from on end silently, last.
    !> limit: write_watchdog_s (60 s, or the environment variable TERRACE_IO_WATCHDOG_S; the
    !> full-disk tests shorten it), plus one second per 10 MiB a section says it moves (a slow
    !> file system writing a large frame is not stuck).
    !> Test hook (tests/regression/io_watchdog_stall.sh): TERRACE_TEST_STALL_RANK=k makes rank k
    !> of MPI_COMM_WORLD stop inside its first slab write as a stuck process would ('k,blocked':
    !> with its own watchdog silenced, as for a process that cannot run at all); unset, the cost
    !> is one integer comparison per slab write.
    integer :: writers_open = 0
    character(len=:), allocatable :: write_label
    integer :: write_watchdog_s = 60
    integer, parameter :: watchdog_grace_s = 3
    integer, parameter :: watchdog_quiet_from = 4
    integer(i8), parameter :: slow_bytes_per_s = 10485760_i8
    integer :: section_depth = 0                   !< nesting of h5_section_begin
    logical :: failure_pending = .false.
    logical, save :: library_open = .false.
    integer :: stall_rank = -1
    logical :: stall_blocked = .false.

contains

    ! ============================================================== status, library, files

    subroutine status_check(self, err, what)
        class(h5_status_t), intent(inout) :: self
        integer, intent(in) :: err
        character(len=*), intent(in) :: what
        if (err < 0 .and. self%ok) then
            self%ok = .false.; self%msg = 'HDF5 error in '//what
            call arm_write_watchdog(self%msg)
        end if
    end subroutine status_check

    subroutine arm_write_watchdog(what)
        character(len=*), intent(in) :: what
        character(len=16) :: s
        if (writers_open <= 0 .or. section_depth > 0) return
        write (s, '(i0)') write_watchdog_s
        call arm_on_rank(write_watchdog_s, 'terrace: error: '//write_label//': '//trim(what)//' and the ranks '// &
                         'did not meet again within '//trim(s)//' s (stuck in HDF5''s collective I/O; is the device full?)')
        failure_pending = .true.
    end subroutine arm_write_watchdog

    !> Guard a collective flush or close of a file open for parallel writing, outside a section:
    !> if it has not returned within write_watchdog_s seconds, one error line and the job ends.
    subroutine h5_guard_begin(what)
        character(len=*), intent(in) :: what
        character(len=16) :: s
        if (writers_open <= 0 .or. failure_pending .or. section_depth > 0) return
        write (s, '(i0)') write_watchdog_s
        call arm_on_rank(write_watchdog_s, 'terrace: error: '//write_label//': HDF5 '//what//' did not return within '// &
                         trim(s)//' s (the ranks are stuck in HDF5''s collective I/O; is the device full?)')
    end subroutine h5_guard_begin

    subroutine h5_guard_end()
        if (.not. failure_pending .and. section_depth == 0) call watchdog_disarm()
    end subroutine h5_guard_end

    !> A collective section on the file `label` names (its path and input key): every rank of the
    !> file's communicator calls it on entering `what` (e.g. 'writing a frame') and
    !> h5_section_end at the end, whatever happened in between. bytes: about what the section
    !> moves over all ranks (a second more per 10 MiB; the same on every rank, so that the ranks'
    !> alarms keep their order). Sections nest; the outermost one arms and disarms.
    subroutine h5_section_begin(label, what, bytes)
        character(len=*), intent(in) :: label, what
        integer(i8), intent(in), optional :: bytes
        character(len=16) :: s
        integer :: limit
        type(h5_status_t) :: st
        section_depth = section_depth + 1
        if (section_depth > 1) return
        call h5_library(st)
        limit = write_watchdog_s
        if (present(bytes)) limit = limit + int(min(max(bytes, 0_i8)/slow_bytes_per_s, 86400_i8))
        write (s, '(i0)') limit
        call arm_on_rank(limit, 'terrace: error: '//label//': '//what//' did not finish on every rank within '// &
                         trim(s)//' s: a rank is stuck in HDF5''s collective I/O (is the device full, or the file '// &
                         'system not answering?)')
    end subroutine h5_section_begin

    !> The end of a collective section (collective over comm, the file's communicator): a barrier,
    !> then the watchdog is disarmed; until every rank has reached it, every rank stays armed.
    subroutine h5_section_end(comm)
        type(MPI_Comm), intent(in) :: comm
        section_depth = max(0, section_depth - 1)
        if (section_depth > 0) return
        call MPI_Barrier(comm)
        failure_pending = .false.
        call watchdog_disarm()
    end subroutine h5_section_end

    !> Arm this process's watchdog so that the job prints one line (see write_watchdog_s above):
    !> rank r fires after seconds + r*watchdog_grace_s; from watchdog_quiet_from on, silently.
    subroutine arm_on_rank(seconds, msg)
        integer, intent(in) :: seconds
        character(len=*), intent(in) :: msg
        integer :: rank
        call MPI_Comm_rank(MPI_COMM_WORLD, rank)
        if (rank < watchdog_quiet_from) then
            call watchdog_arm(seconds + rank*watchdog_grace_s, msg, 1)
        else
            call watchdog_arm(seconds + watchdog_quiet_from*watchdog_grace_s, '', 1)
        end if
    end subroutine arm_on_rank

    !> Guard the opening of a file to read and the reading of its metadata:
    !> on some files with one damaged byte (in HDF5's global heap) HDF5 1.10 spins forever. If
    !> h5_watch_end is not reached within write_watchdog_s seconds, one line
    !> 'terrace: error: <path>: <key>: ...' and exit status 1. Inside a section: nothing (the
    !> section's watchdog is armed).
    subroutine h5_watch_begin(path, key)
        character(len=*), intent(in) :: path, key
        character(len=16) :: s
        if (section_depth > 0) return
        write (s, '(i0)') write_watchdog_s
        call arm_on_rank(write_watchdog_s, 'terrace: error: '//path//': '//key//': opening the file and reading its '// &
                         'metadata did not finish within '//trim(s)//' s: HDF5 is stuck on it (a damaged file, or a '// &
                         'file system that does not answer)')
    end subroutine h5_watch_begin

    subroutine h5_watch_end()
        if (section_depth == 0) call watchdog_disarm()
    end subroutine h5_watch_end

    !> A file opened for parallel writing (h5_open_file with a communicator) has been closed.
    subroutine h5_writer_closed()
        writers_open = max(0, writers_open - 1)
    end subroutine h5_writer_closed

    subroutine status_fail(self, what)
        class(h5_status_t), intent(inout) :: self
        character(len=*), intent(in) :: what
        if (self%ok) then
            self%ok = .false.; self%msg = what
            call arm_write_watchdog(self%msg)
        end if
    end subroutine status_fail

    !> Open the HDF5 library (once per process) and switch its error printing off.
    subroutine h5_library(st)
        type(h5_status_t), intent(inout) :: st
        integer :: err
        if (library_open) return
        call h5open_f(err); call st%check(err, 'H5open')
        call h5eset_auto_f(0, err)
        library_open = st%ok
        block
            character(len=32) :: v
            integer :: n, ios, s
            call get_environment_variable('TERRACE_IO_WATCHDOG_S', v, n)
            if (n > 0) then
                read (v, *, iostat=ios) s
                if (ios == 0 .and. s >= 1) write_watchdog_s = s
            end if
            call get_environment_variable('TERRACE_TEST_STALL_RANK', v, n)
            if (n > 0) then
                read (v, *, iostat=ios) s
                if (ios == 0 .and. s >= 0) stall_rank = s
                stall_blocked = index(v, 'blocked') > 0
            end if
        end block
    end subroutine h5_library

    !> The same ok on every rank of comm; msg is that of the lowest failing rank. Outside a
    !> section, disarms the watchdog a failed parallel write armed (status_check): the ranks are in
    !> step again.
    subroutine h5_agree(comm, st, ok, msg)
        type(MPI_Comm), intent(in) :: comm
        type(h5_status_t), intent(in) :: st
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: rank, nprocs, failing
        character(len=1024) :: m
        call MPI_Comm_rank(comm, rank)
        call MPI_Comm_size(comm, nprocs)
        failing = merge(nprocs, rank, st%ok)
        if (nprocs > 1) call MPI_Allreduce(MPI_IN_PLACE, failing, 1, MPI_INTEGER, MPI_MIN, comm)
        if (section_depth == 0) then
            failure_pending = .false.
            call watchdog_disarm()
        end if
        ok = failing == nprocs
        msg = ''
        if (ok) return
        m = st%msg
        call MPI_Bcast(m, len(m), MPI_CHARACTER, failing, comm)
        msg = m
    end subroutine h5_agree

    !> Open `path` (mode h5_read: read-only; h5_append: read-write) or create it (h5_create:
    !> truncated, HDF5 1.8 object headers so that older readers read it). With comm: through MPI-IO,
    !> collective over comm, and with collective_metadata, metadata writes are collective too.
    !> file < 0 when the file cannot be opened or created (the caller says so); a failure to set
    !> up the access properties is kept in st.
    subroutine h5_open_file(st, path, mode, file, comm, collective_metadata, label)
        type(h5_status_t), intent(inout) :: st
        character(len=*), intent(in) :: path
        integer, intent(in) :: mode
        integer(hid_t), intent(out) :: file
        type(MPI_Comm), intent(in), optional :: comm
        logical, intent(in), optional :: collective_metadata
        character(len=*), intent(in), optional :: label     !< the file and its key, for messages
        integer(hid_t) :: fapl
        integer :: err
        file = -1
        call h5_library(st)
        if (.not. st%ok) return
        call h5pcreate_f(H5P_FILE_ACCESS_F, fapl, err); call st%check(err, 'H5Pcreate(fapl)')
        if (present(comm)) then
            ! a semaphore a killed job left locked would hold up the open forever (file_ops)
            call clear_mpiio_semaphore(path)
            call MPI_Barrier(comm)
            call h5pset_fapl_mpio_f(fapl, comm%MPI_VAL, MPI_INFO_NULL%MPI_VAL, err)
            call st%check(err, 'H5Pset_fapl_mpio')
        end if
        if (mode == h5_create) then
            call h5pset_libver_bounds_f(fapl, H5F_LIBVER_V18_F, H5F_LIBVER_V18_F, err)
            call st%check(err, 'H5Pset_libver_bounds')
        end if
        if (present(collective_metadata)) then
            if (collective_metadata) then
                call h5pset_coll_metadata_write_f(fapl, .true., err); call st%check(err, 'H5Pset_coll_metadata_write')
            end if
        end if
        select case (mode)
        case (h5_create)
            call h5fcreate_f(path, H5F_ACC_TRUNC_F, file, err, access_prp=fapl)
        case (h5_append)
            call h5fopen_f(path, H5F_ACC_RDWR_F, file, err, access_prp=fapl)
        case default
            call h5fopen_f(path, H5F_ACC_RDONLY_F, file, err, access_prp=fapl)
        end select
        if (err < 0) file = -1
        call h5pclose_f(fapl, err)
        if (present(comm) .and. mode /= h5_read .and. file >= 0) then
            writers_open = writers_open + 1
            write_label = path
            if (present(label)) write_label = label
        end if
    end subroutine h5_open_file

    !> A dataset transfer property list for MPI-IO: collective or independent transfers.
    subroutine h5_transfer_list(st, collective, dxpl)
        type(h5_status_t), intent(inout) :: st
        logical, intent(in) :: collective
        integer(hid_t), intent(out) :: dxpl
        integer :: err
        call h5pcreate_f(H5P_DATASET_XFER_F, dxpl, err); call st%check(err, 'H5Pcreate(dxpl)')
        if (collective) then
            call h5pset_dxpl_mpio_f(dxpl, H5FD_MPIO_COLLECTIVE_F, err)
        else
            call h5pset_dxpl_mpio_f(dxpl, H5FD_MPIO_INDEPENDENT_F, err)
        end if
        call st%check(err, 'H5Pset_dxpl_mpio')
    end subroutine h5_transfer_list

    ! ============================================================== datasets

    !> A dataset of fixed shape dims (Fortran order), contiguous, no fill written.
    subroutine h5_make_fixed(st, loc, name, ftype, dims, d)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc, ftype
        character(len=*), intent(in) :: name
        integer(hsize_t), intent(in) :: dims(:)
        integer(hid_t), intent(out) :: d
        integer(hid_t) :: sp, dcpl
        integer :: err
        call h5screate_simple_f(size(dims), dims, sp, err); call st%check(err, 'H5Screate '//name)
        call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, err)
        call h5pset_fill_time_f(dcpl, H5D_FILL_TIME_NEVER_F, err)
        call h5dcreate_f(loc, name, ftype, sp, d, err, dcpl_id=dcpl); call st%check(err, 'H5Dcreate '//name)
        call h5pclose_f(dcpl, err)
        call h5sclose_f(sp, err)
    end subroutine h5_make_fixed

    !> An extendible series: Fortran dims (inner..., 0), unlimited last dimension, chunks
    !> (chunk_inner..., chunk_frames), chunk_frames defaulting to 1, or to 512 for a series of
    !> scalars.
    subroutine h5_make_series(st, loc, name, ftype, inner, chunk_inner, d, chunk_frames)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc, ftype
        character(len=*), intent(in) :: name
        integer(hsize_t), intent(in) :: inner(:), chunk_inner(:)
        integer(hid_t), intent(out) :: d
        integer(hsize_t), intent(in), optional :: chunk_frames
        integer(hid_t) :: sp, dcpl
        integer(hsize_t) :: dims(size(inner) + 1), maxdims(size(inner) + 1), chunk(size(inner) + 1)
        integer :: err, n
        n = size(inner) + 1
        dims(1:n - 1) = inner; dims(n) = 0
        maxdims(1:n - 1) = inner; maxdims(n) = H5S_UNLIMITED_F
        chunk(1:n - 1) = chunk_inner; chunk(n) = merge(chunk_scalar, 1_hsize_t, n == 1)
        if (present(chunk_frames)) chunk(n) = chunk_frames
        call h5screate_simple_f(n, dims, sp, err, maxdims); call st%check(err, 'H5Screate '//name)
        call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, err)
        call h5pset_chunk_f(dcpl, n, chunk, err); call st%check(err, 'H5Pset_chunk '//name)
        call h5pset_fill_time_f(dcpl, H5D_FILL_TIME_NEVER_F, err)
        call h5dcreate_f(loc, name, ftype, sp, d, err, dcpl_id=dcpl); call st%check(err, 'H5Dcreate '//name)
        call h5pclose_f(dcpl, err)
        call h5sclose_f(sp, err)
    end subroutine h5_make_series

    subroutine h5_extend(st, d, dims)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: d
        integer(hsize_t), intent(in) :: dims(:)
        integer :: err
        call h5dset_extent_f(d, dims, err); call st%check(err, 'H5Dset_extent')
    end subroutine h5_extend

    !> Rank of a dataset (0 for a scalar; -1 when it cannot be told).
    integer function h5_dataset_rank(d) result(rank)
        integer(hid_t), intent(in) :: d
        integer(hid_t) :: sp
        integer :: err
        rank = -1
        call h5dget_space_f(d, sp, err)
        if (err < 0) return
        call h5sget_simple_extent_ndims_f(sp, rank, err)
        if (err < 0) rank = -1
        call h5sclose_f(sp, err)
    end function h5_dataset_rank

    !> Fortran-order dims (and maxdims) of a dataset of rank size(dims); st fails for another rank.
    subroutine h5_dataset_dims(st, d, dims, maxdims)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: d
        integer(hsize_t), intent(out) :: dims(:)
        integer(hsize_t), intent(out), optional :: maxdims(:)
        integer(hid_t) :: sp
        integer(hsize_t) :: md(size(dims))
        integer :: err, rank
        dims = 0; md = 0
        call h5dget_space_f(d, sp, err); call st%check(err, 'H5Dget_space')
        call h5sget_simple_extent_ndims_f(sp, rank, err)
        if (rank /= size(dims)) then
            call st%fail('a dataset has an unexpected rank')
        else
            call h5sget_simple_extent_dims_f(sp, dims, md, err); call st%check(err, 'H5Sget_simple_extent_dims')
        end if
        call h5sclose_f(sp, err)
        if (present(maxdims)) maxdims = md
    end subroutine h5_dataset_dims

    !> Transfer of the hyperslab start/count (stride: every stride-th entry along each dimension)
    !> between the file and the contiguous buffer buf (shape count). Through dxpl when given (an
    !> MPI-IO file: collective with a collective list, and then ranks with active = .false. take
    !> part with an empty selection), else with the default (independent) transfer.
    subroutine transfer_slab(st, d, memtype, buf, start, count, active, reading, dxpl, stride)
        include 'hdf5_slab_args.inc'
        logical, intent(in) :: active, reading
        integer(hid_t), intent(in), optional :: dxpl
        integer(hsize_t), intent(in), optional :: stride(:)
        integer(hid_t) :: fsp, msp, xfer
        integer(hsize_t) :: mdims(size(count))
        type(c_ptr) :: bufp
        integer :: err
        xfer = H5P_DEFAULT_F
        if (present(dxpl)) xfer = dxpl
        call h5dget_space_f(d, fsp, err); call st%check(err, 'H5Dget_space')
        if (active .and. all(count > 0)) then
            mdims = count
            call h5screate_simple_f(size(count), mdims, msp, err)
            if (present(stride)) then
                call h5sselect_hyperslab_f(fsp, H5S_SELECT_SET_F, start, count, err, stride=stride)
            else
                call h5sselect_hyperslab_f(fsp, H5S_SELECT_SET_F, start, count, err)
            end if
            call st%check(err, 'H5Sselect_hyperslab')
        else
            mdims = 1
            call h5screate_simple_f(size(count), mdims, msp, err)
            call h5sselect_none_f(msp, err)
            call h5sselect_none_f(fsp, err)
        end if
        call st%check(err, 'dataspace selection')
        if (reading) then
            bufp = buf   ! h5dread_f takes the pointer as intent(inout)
            call h5dread_f(d, memtype, bufp, err, mem_space_id=msp, file_space_id=fsp, xfer_prp=xfer)
            call st%check(err, 'H5Dread')
        else
            call h5dwrite_f(d, memtype, buf, err, mem_space_id=msp, file_space_id=fsp, xfer_prp=xfer)
            call st%check(err, 'H5Dwrite')
        end if
        call h5sclose_f(msp, err)
        call h5sclose_f(fsp, err)
    end subroutine transfer_slab

    subroutine h5_write_slab(st, d, memtype, buf, start, count, active, dxpl)
        include 'hdf5_slab_args.inc'
        logical, intent(in) :: active
        integer(hid_t), intent(in), optional :: dxpl
        if (stall_rank >= 0) call test_stall_here()
        call transfer_slab(st, d, memtype, buf, start, count, active, .false., dxpl)
    end subroutine h5_write_slab

    !> The test hook TERRACE_TEST_STALL_RANK (see write_watchdog_s): rank k stops here, once.
    subroutine test_stall_here()
        integer :: rank
        call MPI_Comm_rank(MPI_COMM_WORLD, rank)
        if (rank /= stall_rank) return
        stall_rank = -1
        call test_stall(3600, stall_blocked)
    end subroutine test_stall_here

    subroutine h5_read_slab(st, d, memtype, buf, start, count, active, dxpl, stride)
        include 'hdf5_slab_args.inc'
        logical, intent(in) :: active
        integer(hid_t), intent(in), optional :: dxpl
        integer(hsize_t), intent(in), optional :: stride(:)
        call transfer_slab(st, d, memtype, buf, start, count, active, .true., dxpl, stride)
    end subroutine h5_read_slab

    !> The whole dataset d into buf (which must be large enough).
    subroutine h5_read_whole(st, d, memtype, buf, what)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: d, memtype
        type(c_ptr), intent(in) :: buf
        character(len=*), intent(in) :: what
        type(c_ptr) :: q
        integer :: err
        q = buf
        call h5dread_f(d, memtype, q, err)
        call st%check(err, 'H5Dread '//what)
    end subroutine h5_read_whole

    !> Element `index` (0-based) of the 1-D dataset `name`.
    subroutine h5_read_at(st, file, name, memtype, buf, index, dxpl)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: file, memtype
        character(len=*), intent(in) :: name
        type(c_ptr), intent(in) :: buf
        integer(hsize_t), intent(in) :: index
        integer(hid_t), intent(in), optional :: dxpl
        integer(hid_t) :: d
        integer :: err
        call h5dopen_f(file, name, d, err); call st%check(err, 'open '//name)
        if (err < 0) return
        call h5_read_slab(st, d, memtype, buf, [index], [1_hsize_t], .true., dxpl)
        call h5dclose_f(d, err)
    end subroutine h5_read_at

    !> Does every component of the absolute path exist (links only; no error printed)?
    logical function h5_link_exists(file, path) result(exists)
        integer(hid_t), intent(in) :: file
        character(len=*), intent(in) :: path
        integer :: i, err
        exists = .true.
        do i = 2, len(path)
            if (path(i:i) == '/' .or. i == len(path)) then
                if (path(i:i) == '/') then
                    call h5lexists_f(file, path(1:i - 1), exists, err)
                else
                    call h5lexists_f(file, path, exists, err)
                end if
                if (err < 0) exists = .false.
                if (.not. exists) return
            end if
        end do
    end function h5_link_exists

    ! ============================================================== attributes: writing

    !> Attribute `name` of file type ftype from buf (memory type memtype): a scalar (n = 0) or n
    !> values in a 1-D dataspace.
    subroutine write_attr(st, loc, name, ftype, memtype, buf, n)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc, ftype, memtype
        character(len=*), intent(in) :: name
        type(c_ptr), intent(in) :: buf
        integer, intent(in) :: n
        integer(hid_t) :: sp, a
        integer :: err
        if (n == 0) then
            call h5screate_f(H5S_SCALAR_F, sp, err)
        else
            call h5screate_simple_f(1, [int(n, hsize_t)], sp, err)
        end if
        call h5acreate_f(loc, name, ftype, sp, a, err); call st%check(err, 'H5Acreate '//name)
        call h5awrite_f(a, memtype, buf, err); call st%check(err, 'H5Awrite '//name)
        call h5aclose_f(a, err)
        call h5sclose_f(sp, err)
    end subroutine write_attr

    !> Integer attribute (int32): a scalar (scalar = .true., one value) or a 1-D array.
    subroutine h5_attr_int(st, loc, name, vals, scalar)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        integer, intent(in) :: vals(:)
        logical, intent(in) :: scalar
        integer(int32), allocatable, target :: buf(:)
        allocate (buf(size(vals)))
        buf = int(vals, int32)
        call write_attr(st, loc, name, H5T_STD_I32LE, h5kind_to_type(int32, H5_INTEGER_KIND), c_loc(buf), &
                        merge(0, size(vals), scalar))
    end subroutine h5_attr_int

    !> Scalar attribute: an int64 (integer(i8)) or a float64 (real(dp)) v.
    subroutine h5_attr_scalar(st, loc, name, v)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        class(*), intent(in), target :: v
        select type (v)
        type is (integer(i8))
            call write_attr(st, loc, name, H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(v), 0)
        type is (real(dp))
            call write_attr(st, loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, c_loc(v), 0)
        class default
            call st%fail('attribute '//name//': only integer(i8) and real(dp) scalars are written')
        end select
    end subroutine h5_attr_scalar

    !> Fixed-length (null-padded) string attribute of scalar dataspace (trailing blanks dropped).
    subroutine h5_attr_text(st, loc, name, s)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name, s
        call h5_attr_text_list(st, loc, name, [s], scalar=.true.)
    end subroutine h5_attr_text

    !> Fixed-length (null-padded) strings, as a 1-D attribute (or scalar for a single string).
    subroutine h5_attr_text_list(st, loc, name, strs, scalar)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name, strs(:)
        logical, intent(in), optional :: scalar
        character(kind=c_char), allocatable, target :: buf(:)
        integer(hid_t) :: t
        integer(size_t) :: w
        integer :: err, i, j, n
        n = size(strs)
        w = 1
        do i = 1, n
            w = max(w, int(len_trim(strs(i)), size_t))
        end do
        allocate (buf(w*n))
        buf = c_null_char
        do i = 1, n
            do j = 1, len_trim(strs(i))
                buf((i - 1)*w + j) = strs(i)(j:j)
            end do
        end do
        call h5tcopy_f(H5T_C_S1, t, err)
        call h5tset_size_f(t, w, err)
        call h5tset_strpad_f(t, H5T_STR_NULLPAD_F, err); call st%check(err, 'string type '//name)
        call write_attr(st, loc, name, t, t, c_loc(buf), merge(0, n, present(scalar)))
        call h5tclose_f(t, err)
    end subroutine h5_attr_text_list

    !> Variable-length ASCII string attribute of scalar dataspace (the H5MD units module's `unit`
    !> and `system`); nothing is written for an empty string.
    subroutine h5_attr_vltext(st, loc, name, s)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name, s
        character(kind=c_char), allocatable, target :: chars(:)
        type(c_ptr), target :: p(1)
        integer(hid_t) :: t
        integer :: err, j, n
        n = len_trim(s)
        if (n == 0) return
        allocate (chars(n + 1))
        do j = 1, n
            chars(j) = s(j:j)
        end do
        chars(n + 1) = c_null_char
        p(1) = c_loc(chars)
        call h5tcopy_f(H5T_STRING, t, err)
        call h5tset_cset_f(t, H5T_CSET_ASCII_F, err); call st%check(err, 'VL string type '//name)
        call write_attr(st, loc, name, t, t, c_loc(p), 0)
        call h5tclose_f(t, err)
    end subroutine h5_attr_vltext

    ! ============================================================== attributes: reading

    !> A scalar attribute read as v's type (integer(i8) or real(dp), converted by HDF5 from the
    !> file's); st fails when it is missing or unreadable (v is then left unchanged).
    !> With if_present, a missing attribute is no failure (v keeps its value).
    subroutine h5_read_attr_scalar(st, loc, name, v, if_present)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        class(*), intent(inout), target :: v
        logical, intent(in), optional :: if_present
        logical :: exists
        integer :: err
        if (present(if_present)) then
            call h5aexists_f(loc, name, exists, err)
            if (if_present .and. (err < 0 .or. .not. exists)) return
        end if
        select type (v)
        type is (integer(i8))
            call read_attr(st, loc, name, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(v))
        type is (real(dp))
            call read_attr(st, loc, name, H5T_NATIVE_DOUBLE, c_loc(v))
        class default
            call st%fail('attribute '//name//': only integer(i8) and real(dp) scalars are read')
        end select
    end subroutine h5_read_attr_scalar

    subroutine read_attr(st, loc, name, memtype, buf)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc, memtype
        character(len=*), intent(in) :: name
        type(c_ptr), intent(in) :: buf
        integer(hid_t) :: a
        integer :: err
        type(c_ptr) :: q
        call h5aopen_f(loc, name, a, err); call st%check(err, 'open attribute '//name)
        if (err < 0) return
        q = buf
        call h5aread_f(a, memtype, q, err); call st%check(err, 'read attribute '//name)
        call h5aclose_f(a, err)
    end subroutine read_attr

    !> A string attribute (scalar or 1-D; fixed- or variable-length strings, ASCII or UTF-8) as a
    !> list of strings of list's length (longer strings are cut). ok = .false. (and an empty list)
    !> when it is absent, not a string or unreadable.
    subroutine h5_read_attr_strings(loc, name, list, ok)
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        character(len=*), allocatable, intent(out) :: list(:)
        logical, intent(out) :: ok
        integer(hid_t) :: a, ftype, mtype, sp
        integer(hssize_t) :: npoints
        integer(size_t) :: width
        integer :: err, i, j, n, w, tclass, cset
        logical :: exists, vl
        character(kind=c_char), allocatable, target :: chars(:)
        type(c_ptr), allocatable, target :: ptrs(:)
        character(kind=c_char), pointer :: cs(:)
        ok = .false.
        allocate (list(0))
        call h5aexists_f(loc, name, exists, err)
        if (err < 0 .or. .not. exists) return
        call h5aopen_f(loc, name, a, err)
        if (err < 0) return
        call h5aget_type_f(a, ftype, err)
        call h5tget_class_f(ftype, tclass, err)
        if (tclass /= H5T_STRING_F) then
            call h5tclose_f(ftype, err); call h5aclose_f(a, err); return
        end if
        call h5aget_space_f(a, sp, err)
        call h5sget_simple_extent_npoints_f(sp, npoints, err)
        call h5sclose_f(sp, err)
        n = int(npoints)
        w = len(list)
        deallocate (list)
        allocate (list(n))
        list = ''
        call h5tis_variable_str_f(ftype, vl, err)
        call h5tget_cset_f(ftype, cset, err)     ! ASCII (Terrace) or UTF-8 (h5py): convert within the set
        if (vl) then
            allocate (ptrs(n))
            call h5tcopy_f(H5T_STRING, mtype, err)
            call h5tset_cset_f(mtype, cset, err)
            call aread(a, mtype, c_loc(ptrs), err)
            if (err >= 0) then
                do i = 1, n
                    if (.not. c_associated(ptrs(i))) cycle
                    call c_f_pointer(ptrs(i), cs, [w])
                    do j = 1, w
                        if (cs(j) == c_null_char) exit
                        list(i)(j:j) = cs(j)
                    end do
                end do
            end if
        else
            call h5tget_size_f(ftype, width, err)
            width = width + 1          ! room for the terminating null of the memory type
            allocate (chars(int(width)*n))
            chars = c_null_char
            call h5tcopy_f(H5T_C_S1, mtype, err)
            call h5tset_size_f(mtype, width, err)
            call h5tset_cset_f(mtype, cset, err)
            call aread(a, mtype, c_loc(chars), err)
            if (err >= 0) then
                do i = 1, n
                    do j = 1, min(w, int(width))
                        if (chars((i - 1)*int(width) + j) == c_null_char) exit
                        list(i)(j:j) = chars((i - 1)*int(width) + j)
                    end do
                end do
            end if
        end if
        ok = err >= 0
        call h5tclose_f(mtype, err)
        call h5tclose_f(ftype, err)
        call h5aclose_f(a, err)
    end subroutine h5_read_attr_strings

    !> The first string of a string attribute; '' when absent or unreadable.
    subroutine h5_read_attr_string(loc, name, s)
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        character(len=*), intent(out) :: s
        character(len=len(s)), allocatable :: list(:)
        logical :: ok
        s = ''
        call h5_read_attr_strings(loc, name, list, ok)
        if (ok) then
            if (size(list) >= 1) s = list(1)
        end if
    end subroutine h5_read_attr_string

    subroutine aread(a, memtype, p, err)
        integer(hid_t), intent(in) :: a, memtype
        type(c_ptr), intent(in) :: p
        integer, intent(out) :: err
        type(c_ptr) :: q
        q = p
        call h5aread_f(a, memtype, q, err)
    end subroutine aread


    !> Open the group name under loc, creating it when it does not exist yet.
    subroutine h5_group(st, loc, name, g)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        integer(hid_t), intent(out) :: g
        logical :: exists
        integer :: err
        call h5lexists_f(loc, name, exists, err); call st%check(err, 'H5Lexists')
        if (exists) then
            call h5gopen_f(loc, name, g, err); call st%check(err, 'open '//name)
        else
            call h5gcreate_f(loc, name, g, err); call st%check(err, 'create '//name)
        end if
    end subroutine h5_group

end module terrace_hdf5_io
