!> Reading H5MD trajectories (Terrace's own files and other H5MD 1.0/1.1 writers): the one reader
!> behind terrace-analyze (h5md_trajectory_t) and the engine's start from a frame (h5md_read_frame).
!>
!> What is read (particles/<group>, group 'all' by default):
!>   position/value, velocity/value   Float[frames][N][D]   (Fortran: (D, N, frames))
!>   image/value                      Integer[frames][N][D] (optional; unwraps periodic positions)
!>   <element>/time, <element>/step   a 1-D dataset of one value per frame, or a scalar dataset
!>                                    (value of frame k = offset + k * value, attribute `offset`
!>                                    optional) as H5MD allows for regularly sampled elements
!>   box                              attribute boundary ('periodic' | 'none', D strings, fixed- or
!>                                    variable-length), and edges: a time-independent dataset
!>                                    edges[D] (or a diagonal edges[D][D]), or a time-dependent
!>                                    element edges/value[frames][D] (one box per frame; a box
!>                                    series of another length is matched to the frames by step:
!>                                    the last box whose step is not after the frame's)
!>   id, species, mass                Integer[N], Integer[N], Float[N] (optional, time-independent)
!>   `unit` attributes of position/value and of the time (optional; used in the CSV headers)
!>
!> Every process opens the file read-only with HDF5's default (POSIX) driver and reads its own
!> hyperslabs independently, so a reader can split the work over frames (one frame, all atoms) or
!> over atoms (a block of atoms, all frames) in any pattern. open either stops every rank through
!> the collective error path (terrace-analyze: every rank checks the same file) or returns ok/msg
!> (h5md_read_frame, which makes its ranks agree over its own communicator).
module terrace_h5md_reader
    use, intrinsic :: iso_c_binding, only: c_ptr, c_loc, c_f_pointer
    use terrace_kinds, only: dp, i8
    use terrace_errors, only: check_all, abort_all
    use terrace_id_blocks, only: id_block
    use terrace_hdf5_io, only: h5_status_t, h5_library, h5_watch_begin, h5_watch_end, h5_agree, h5_open_file, h5_read, h5_link_exists, &
                               h5_dataset_rank, h5_dataset_dims, h5_read_whole, h5_read_slab, &
                               h5_read_attr_scalar, h5_read_attr_strings, h5_read_attr_string
    use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size
    use terrace_mpi_env, only: world
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use hdf5, only: hid_t, hsize_t, h5dopen_f, h5dclose_f, h5gopen_f, h5gclose_f, h5fclose_f, h5aexists_f, &
                    h5kind_to_type, H5_INTEGER_KIND, H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER
    implicit none
    private

    integer, parameter, public :: el_position = 1, el_velocity = 2, el_image = 3
    character(len=8), parameter :: el_name(3) = [character(len=8) :: 'position', 'velocity', 'image']
    !> Largest magnitude of a position, velocity or box edge read from a file, in the file's units
    !> (as for a data file's box bounds): beyond it nothing the engine or the analyses compute
    !> with it means anything (a position of 1e300 wraps to noise), so it is damage.
    real(dp), parameter :: value_limit = 1.0e9_dp

    !> One time-dependent particle element.
    type :: element_t
        logical :: present = .false.
        integer(hid_t) :: value = -1
        integer(i8) :: nframes = 0
        real(dp), allocatable :: time(:)         !< time of each frame (empty if the file has none)
        logical :: has_time = .false.
        integer(i8), allocatable :: step(:)      !< step of each frame (empty if the file has none)
        logical :: has_step = .false.
    end type element_t

    type, public :: h5md_trajectory_t
        character(len=:), allocatable :: path
        character(len=:), allocatable :: group       !< '/particles/<name>'
        character(len=:), allocatable :: key         !< the input key that names the file (messages)
        integer(hid_t) :: file = -1
        integer(i8) :: natoms = 0
        integer :: dimension = 0
        logical :: periodic(3) = .false.
        type(element_t) :: el(3)
        real(dp), allocatable :: edges(:, :)         !< (3, nbox): nbox = 1 for a fixed box
        integer(i8), allocatable :: box_step(:)      !< step of each box of a series (when given)
        logical :: box_series = .false.              !< edges given per frame (edges/value)
        logical :: has_box = .false.
        integer :: box_element = el_position         !< the element whose frames the boxes follow
        integer, allocatable :: species(:)
        real(dp), allocatable :: mass(:)
        character(len=32) :: unit_length = '', unit_time = '', unit_velocity = ''
        integer(i8) :: values_checked(3, 3) = -1      !< (f0, nsel, stride) check_values last passed, per element
    contains
        procedure :: open => traj_open
        procedure :: close => traj_close
        procedure :: has => traj_has
        procedure :: frames => traj_frames
        procedure :: time_of => traj_time_of
        procedure :: box_edges => traj_box_edges
        procedure :: read_real => traj_read
        procedure :: read_int => traj_read
        procedure :: where => traj_where
        procedure :: check_values => traj_check_values
        procedure :: time_step => traj_time_step
    end type h5md_trajectory_t

    integer(i8), parameter :: frames_per_read = 1024

    public :: h5md_read_frame

    !> One frame as h5md_read_frame reads it: this rank's block of ids (ids, types, and x, v, image
    !> (3, nlocal), zero beyond the file's dimension; v and image zero when the file has no velocity
    !> or image: has_velocity, has_image say). types are 1 when the file has no species; ids are
    !> row+1 without an id element. edges is the box edge vector (hi - lo) at the frame when the
    !> file has a box. step is the frame's (position/step); time is 0 without a time.
    type, public :: h5md_frame_t
        integer(i8) :: natoms = 0
        integer :: dimension = 0
        integer(i8), allocatable :: ids(:)
        integer, allocatable :: types(:)
        real(dp), allocatable :: x(:, :), v(:, :)
        integer, allocatable :: image(:, :)
        integer(i8) :: step = 0
        real(dp) :: time = 0
        logical :: has_velocity = .false., has_image = .false.
        real(dp) :: edges(3) = 0
    end type h5md_frame_t

contains

    !> "FILE: /particles/all/<what>" for messages.
    function traj_where(self, what) result(s)
        class(h5md_trajectory_t), intent(in) :: self
        character(len=*), intent(in) :: what
        character(len=:), allocatable :: s
        s = self%path//': '//self%key//': '//self%group//'/'//what
    end function traj_where

    !> Every value of element e (el_position or el_velocity) in the frames f0+1, f0+1+stride, ...
    !> (nsel of them, 0-based f0) is finite and at most value_limit in magnitude; otherwise one
    !> error naming the file, the dataset, the frame and the atom row stops every rank. Collective
    !> over MPI_COMM_WORLD: the frames are shared among the ranks, one frame read at a time (the
    !> analyses call it while planning, before any output is written).
    subroutine traj_check_values(self, e, f0, nsel, stride)
        class(h5md_trajectory_t), intent(inout) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: f0, nsel, stride
        type(h5_status_t) :: st
        real(dp), allocatable, target :: buf(:, :)
        integer(i8) :: j
        if (all(self%values_checked(:, e) == [f0, nsel, stride])) return   ! the same frames again
        if (self%el(e)%present .and. self%natoms > 0) then
            allocate (buf(self%dimension, self%natoms))
            do j = world%rank, nsel - 1, world%nprocs
                call read_block(self, e, f0 + j*stride, 1_i8, 1_i8, 0_i8, self%natoms, H5T_NATIVE_DOUBLE, c_loc(buf), &
                                size(buf, kind=i8), st)
                if (.not. st%ok) exit
            end do
        end if
        call check_all(st%ok, trim(st%msg))
        self%values_checked(:, e) = [f0, nsel, stride]
    end subroutine traj_check_values

    !> Record `text` as the failure when cond is false; .true. once the sequence has failed.
    logical function failed(st, cond, text)
        type(h5_status_t), intent(inout) :: st
        logical, intent(in) :: cond
        character(len=*), intent(in) :: text
        if (.not. cond) call st%fail(text)
        failed = .not. st%ok
    end function failed

    !> Open `path` and read everything small: shapes, times, steps, box, and (unless constants =
    !> .false.) species and masses. `group` is the particles group ('all'). need_velocity /
    !> need_position: the caller needs them (their absence is an error naming the dataset and the
    !> reason `why_*`). Without ok, an error stops every rank of the run (collective); with ok, it
    !> is returned in ok/msg on this process (nothing collective). key names the file's input key
    !> in messages (default 'trajectory_file').
    subroutine traj_open(self, path, group, need_position, need_velocity, why_position, why_velocity, ok, msg, &
                         constants, key)
        class(h5md_trajectory_t), intent(inout) :: self
        character(len=*), intent(in) :: path, group
        logical, intent(in) :: need_position, need_velocity
        character(len=*), intent(in) :: why_position, why_velocity
        logical, intent(out), optional :: ok
        character(len=*), intent(out), optional :: msg
        logical, intent(in), optional :: constants
        character(len=*), intent(in), optional :: key
        type(h5_status_t) :: st
        logical :: read_constants

        read_constants = .true.
        if (present(constants)) read_constants = constants
        self%key = 'trajectory_file'
        if (present(key)) self%key = key
        call h5_library(st)
        call h5_watch_begin(trim(path), self%key)
        call open_file(self, st, path, group, need_position, need_velocity, why_position, why_velocity, read_constants)
        call h5_watch_end()
        if (.not. st%ok) call self%close()
        if (present(ok)) then
            ok = st%ok
            if (present(msg)) msg = st%msg
        else
            call check_all(st%ok, trim(st%msg))
        end if
    end subroutine traj_open

    subroutine open_file(self, st, path, group, need_position, need_velocity, why_position, why_velocity, &
                         read_constants)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        character(len=*), intent(in) :: path, group
        logical, intent(in) :: need_position, need_velocity, read_constants
        character(len=*), intent(in) :: why_position, why_velocity
        integer :: e, k
        logical :: exists
        integer(hsize_t) :: ref(3)
        integer(i8) :: fsize

        self%path = trim(path)
        self%group = '/particles/'//trim(group)
        call h5_library(st)
        if (.not. st%ok) return
        inquire (file=self%path, exist=exists)
        if (failed(st, exists, self%path//': '//self%key//': cannot open (no such file)')) return
        fsize = file_bytes(self%path)
        call h5_open_file(st, self%path, h5_read, self%file)
        if (failed(st, self%file >= 0, self%path//': '//self%key//': cannot open as HDF5 (not an HDF5/H5MD file?)')) &
            return
        if (self%key == 'trajectory_file') then
            if (failed(st, h5_link_exists(self%file, self%group), self%path//': '//self%key//': '//self%group// &
                       ': missing (no particles group of that name; set &analysis particles_group)')) return
        else
            if (failed(st, h5_link_exists(self%file, self%group), self%path//': '//self%key//': '//self%group// &
                       ': missing (no particles group of that name)')) return
        end if

        ! ---- the elements and their shapes
        ref = 0
        do e = 1, 3
            call open_element(self, st, e, fsize, ref)
            if (.not. st%ok) return
        end do
        call check_elements(self, st, need_position, need_velocity, why_position, why_velocity)
        if (.not. st%ok) return
        self%dimension = int(ref(1))
        self%natoms = int(ref(2), i8)

        call read_box(self, st)
        if (.not. st%ok) return

        ! ---- per-atom constants
        if (read_constants) then
            allocate (self%species(self%natoms), self%mass(self%natoms))
            self%species = 1; self%mass = 1
            if (h5_link_exists(self%file, self%group//'/species')) &
                call read_atom_constant(self, st, 'species', 0_i8, self%natoms, ints=self%species)
            if (h5_link_exists(self%file, self%group//'/mass')) &
                call read_atom_constant(self, st, 'mass', 0_i8, self%natoms, reals=self%mass)
            if (.not. st%ok) return
        end if
        if (self%el(el_position)%present) &
            call h5_read_attr_string(self%el(el_position)%value, 'unit', self%unit_length)
        if (self%el(el_velocity)%present) &
            call h5_read_attr_string(self%el(el_velocity)%value, 'unit', self%unit_velocity)
        do k = 1, 3
            if (len_trim(self%unit_time) > 0) exit
            if (self%el(k)%present) self%unit_time = time_unit(self, k)
        end do
    end subroutine open_file

    !> Element e's value dataset, when there is one: opened, its shape checked against the file's
    !> size (fsize bytes) and against the elements opened before (ref: the first one's dims, 0 before
    !> it), and its time and step read.
    subroutine open_element(self, st, e, fsize, ref)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        integer, intent(in) :: e
        integer(i8), intent(in) :: fsize
        integer(hsize_t), intent(inout) :: ref(3)
        integer(hsize_t) :: dims(3)
        character(len=24) :: a, b, c
        character(len=:), allocatable :: vname
        integer :: err
        associate (el => self%el(e))
            vname = trim(el_name(e))//'/value'
            el%present = h5_link_exists(self%file, self%group//'/'//vname)
            if (.not. el%present) return
            call h5dopen_f(self%file, self%group//'/'//vname, el%value, err)
            if (failed(st, err >= 0, self%where(vname)//': cannot open the dataset')) return
            if (failed(st, h5_dataset_rank(el%value) == 3, self%where(vname)// &
                       ': wrong shape (expected [frames][atoms][dimension])')) return
            call h5_dataset_dims(st, el%value, dims)
            if (failed(st, dims(1) >= 1 .and. dims(1) <= 3 .and. dims(2) >= 1, self%where(vname)// &
                       ': wrong shape (dimension must be 1..3, at least one atom)')) return
            ! a declared shape costs nothing in the file (chunks never written): every frame and
            ! every atom takes at least a byte of it, so neither count can exceed its size
            write (a, '(i0)') dims(3); write (b, '(i0)') dims(2); write (c, '(i0)') fsize
            if (failed(st, int(dims(3), i8) <= fsize .and. int(dims(2), i8) <= fsize, self%where(vname)// &
                       ': declares '//trim(a)//' frames of '//trim(b)//' atoms, more than a file of '//trim(c)// &
                       ' bytes can hold (damaged or not written in full?)')) return
            if (all(ref == 0)) then
                ref = dims
            else if (any(dims(1:2) /= ref(1:2))) then
                write (a, '(i0,a,i0)') ref(2), ' x ', ref(1)
                write (b, '(i0,a,i0)') dims(2), ' x ', dims(1)
                call st%fail(self%where(vname)//': wrong shape ('//trim(b)// &
                             ' atoms x dimension; the other elements have '//trim(a)//')')
                return
            end if
            el%nframes = int(dims(3), i8)
            call read_clock(self, st, e, 'time')
            call read_clock(self, st, e, 'step')
        end associate
    end subroutine open_element

    !> The elements opened: image as long as position; position and velocity there when needed
    !> (why_*: what needs them); at least one of them.
    subroutine check_elements(self, st, need_position, need_velocity, why_position, why_velocity)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        logical, intent(in) :: need_position, need_velocity
        character(len=*), intent(in) :: why_position, why_velocity
        character(len=24) :: a, b
        if (self%el(el_image)%present .and. self%el(el_position)%present) then
            write (a, '(i0)') self%el(el_position)%nframes
            write (b, '(i0)') self%el(el_image)%nframes
            if (failed(st, self%el(el_image)%nframes == self%el(el_position)%nframes, self%where('image/value')// &
                       ': wrong shape ('//trim(b)//' frames, position/value has '//trim(a)//')')) return
        end if
        if (need_position) then
            if (failed(st, self%el(el_position)%present, self%where('position/value')//': missing ('// &
                       why_position//')')) return
        end if
        if (need_velocity) then
            if (failed(st, self%el(el_velocity)%present, self%where('velocity/value')//': missing ('// &
                       why_velocity//')')) return
        end if
        if (failed(st, any(self%el(:)%present), self%where('position/value')//': missing (no position or '// &
                   'velocity element: nothing to analyse)')) return
    end subroutine check_elements

    !> The size of the file in bytes (0 when it cannot be asked).
    integer(i8) function file_bytes(path) result(n)
        character(len=*), intent(in) :: path
        inquire (file=path, size=n)
        n = max(n, 0_i8)
    end function file_bytes

    !> The time (what = 'time') or step (what = 'step') of every frame of element e: a dataset
    !> [frames], or a scalar increment with an optional offset attribute. A time that is there but
    !> not readable is an error; absent (or a step not of this shape): has_time / has_step .false.
    subroutine read_clock(self, st, e, what)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        integer, intent(in) :: e
        character(len=*), intent(in) :: what
        integer(hid_t) :: d
        integer :: err, rank
        integer(hsize_t) :: dims(1)
        integer(i8) :: k
        real(dp), target :: scal(1)
        real(dp) :: offset
        integer(i8), target :: iscal(1)
        integer(i8) :: ioffset
        real(dp), allocatable, target :: times(:)
        integer(i8), allocatable, target :: steps(:)
        character(len=:), allocatable :: name, tag
        character(len=16) :: s1, s2
        logical :: is_time
        type(h5_status_t) :: lenient
        is_time = what == 'time'
        associate (el => self%el(e))
            tag = trim(el_name(e))//'/'//what
            name = self%group//'/'//tag
            if (is_time) then
                allocate (el%time(0))
            else
                allocate (el%step(0))
            end if
            if (.not. h5_link_exists(self%file, name)) return
            call h5dopen_f(self%file, name, d, err)
            if (.not. is_time) then
                ! steps are read where they are well formed; nothing depends on them otherwise
                if (err < 0) return
                rank = h5_dataset_rank(d)
                if (rank == 0) then
                    call h5_read_whole(lenient, d, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(iscal), tag)
                    ioffset = 0
                    call h5_read_attr_scalar(lenient, d, 'offset', ioffset, if_present=.true.)
                    el%step = [(ioffset + (k - 1)*iscal(1), k = 1, el%nframes)]
                else if (rank == 1) then
                    call h5_dataset_dims(lenient, d, dims)
                    if (int(dims(1), i8) == el%nframes) then
                        allocate (steps(el%nframes))
                        if (el%nframes > 0) call h5_read_whole(lenient, d, h5kind_to_type(i8, H5_INTEGER_KIND), &
                                                               c_loc(steps), tag)
                        call move_alloc(steps, el%step)
                    else
                        call lenient%fail('steps')
                    end if
                else
                    call lenient%fail('steps')
                end if
                el%has_step = lenient%ok
                call h5dclose_f(d, err)
                return
            end if
            if (failed(st, err >= 0, self%where(tag)//': cannot open the dataset')) return
            rank = h5_dataset_rank(d)
            if (rank == 0) then
                call h5_read_whole(st, d, H5T_NATIVE_DOUBLE, c_loc(scal), tag)
                if (failed(st, st%ok, self%where(tag)//': cannot read')) return
                offset = 0
                call h5_read_attr_scalar(st, d, 'offset', offset, if_present=.true.)
                el%time = [(offset + real(k - 1, dp)*scal(1), k = 1, el%nframes)]
            else
                if (failed(st, rank == 1, self%where(tag)// &
                           ': wrong shape (expected time[frames] or a scalar time step)')) return
                call h5_dataset_dims(st, d, dims)
                write (s1, '(i0)') dims(1); write (s2, '(i0)') el%nframes
                if (failed(st, int(dims(1), i8) == el%nframes, self%where(tag)//': wrong shape ('//trim(s1)// &
                           ' times for '//trim(s2)//' frames of '//trim(el_name(e))//'/value)')) return
                deallocate (el%time)
                allocate (times(el%nframes))
                if (el%nframes > 0) then
                    call h5_read_whole(st, d, H5T_NATIVE_DOUBLE, c_loc(times), tag)
                    if (failed(st, st%ok, self%where(tag)//': cannot read')) return
                end if
                call move_alloc(times, el%time)
            end if
            el%has_time = .true.
            call h5dclose_f(d, err)
        end associate
    end subroutine read_clock

    function time_unit(self, e) result(u)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        character(len=32) :: u
        integer(hid_t) :: d
        integer :: err
        u = ''
        if (.not. self%el(e)%has_time) return
        call h5dopen_f(self%file, self%group//'/'//trim(el_name(e))//'/time', d, err)
        if (err < 0) return
        call h5_read_attr_string(d, 'unit', u)
        call h5dclose_f(d, err)
    end function time_unit

    !> The box: boundary attribute and edges (fixed dataset, diagonal matrix, or edges/value series).
    subroutine read_box(self, st)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        character(len=:), allocatable :: bname, ename
        character(len=32), allocatable :: boundary(:)
        integer(hid_t) :: g, d
        integer :: err, k, Dm
        logical :: ok

        Dm = self%dimension
        allocate (self%edges(3, 1))
        self%edges = 0
        bname = self%group//'/box'
        self%has_box = h5_link_exists(self%file, bname)
        if (.not. self%has_box) return
        call h5gopen_f(self%file, bname, g, err)
        if (failed(st, err >= 0, self%where('box')//': cannot open the group')) return
        call h5_read_attr_strings(g, 'boundary', boundary, ok)
        ename = bname//'/edges'
        if (h5_link_exists(self%file, ename)) then
            call h5dopen_f(self%file, ename, d, err)
            if (err >= 0) then
                call read_fixed_edges(self, st, d)
            else
                call read_edges_series(self, st, ename)
            end if
            if (.not. st%ok) return
        end if
        if (failed(st, all(ieee_is_finite(self%edges(1:Dm, :))), self%where('box/edges')// &
                   ': NaN or infinite value in the file')) return
        if (failed(st, all(abs(self%edges(1:Dm, :)) <= value_limit), self%where('box/edges')// &
                   ': a value beyond 1e9 in magnitude (allowed: |edge| <= 1e9 in the file''s units)')) return
        if (ok) then
            if (failed(st, size(boundary) == Dm, self%where('box')//': boundary attribute: wrong length '// &
                       '(one entry per dimension)')) return
            do k = 1, Dm
                select case (trim(boundary(k)))
                case ('periodic')
                    self%periodic(k) = .true.
                case ('none')
                case default
                    call st%fail(self%where('box')//": boundary attribute: unknown value '"// &
                                 trim(boundary(k))//"' (allowed: 'periodic', 'none')")
                    return
                end select
            end do
        else
            ! no boundary attribute: periodic where an edge is given
            self%periodic(1:Dm) = any(self%edges(1:Dm, :) > 0)
        end if
        do k = 1, Dm
            if (self%periodic(k)) then
                if (failed(st, all(self%edges(k, :) > 0), self%where('box/edges')// &
                           ': a periodic edge is missing or not positive')) return
            end if
        end do
        call h5gclose_f(g, err)
    end subroutine read_box

    !> A time-independent box/edges dataset d (open): edges[D] or the diagonal of edges[D][D].
    subroutine read_fixed_edges(self, st, d)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: d
        real(dp), allocatable, target :: m(:, :)
        integer(hsize_t) :: dims(2)
        integer :: err, rank, k, Dm
        Dm = self%dimension
        rank = h5_dataset_rank(d)
        if (failed(st, rank == 1 .or. rank == 2, self%where('box/edges')// &
                   ': wrong shape (expected edges[dimension] or edges[dimension][dimension])')) return
        call h5_dataset_dims(st, d, dims(1:rank))
        if (failed(st, all(int(dims(1:rank)) == Dm), self%where('box/edges')// &
                   ': wrong shape (the box dimension differs from that of the particle data)')) return
        allocate (m(Dm, merge(Dm, 1, rank == 2)))
        call h5_read_whole(st, d, H5T_NATIVE_DOUBLE, c_loc(m), 'box/edges')
        if (failed(st, st%ok, self%where('box/edges')//': cannot read')) return
        if (rank == 1) then
            self%edges(1:Dm, 1) = m(:, 1)
        else
            do k = 1, Dm
                self%edges(k, 1) = m(k, k)
                m(k, k) = 0
            end do
            if (failed(st, all(m == 0), self%where('box/edges')// &
                       ': a triclinic box (off-diagonal edges) is not supported')) return
        end if
        call h5dclose_f(d, err)
    end subroutine read_fixed_edges

    !> A time-dependent box/edges element (the group ename): value[frames][D], one row per frame
    !> (or one for all), and the boxes' own steps when given.
    subroutine read_edges_series(self, st, ename)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        character(len=*), intent(in) :: ename
        real(dp), allocatable, target :: series(:, :)
        integer(hid_t) :: d
        integer(hsize_t) :: dims(2)
        integer :: err, k, Dm
        character(len=16) :: s1, s2
        Dm = self%dimension
        if (failed(st, h5_link_exists(self%file, ename//'/value'), self%where('box/edges/value')// &
                   ': missing (box/edges is a group, so it must be a time-dependent element)')) return
        call h5dopen_f(self%file, ename//'/value', d, err)
        if (failed(st, err >= 0, self%where('box/edges/value')//': cannot open the dataset')) return
        if (failed(st, h5_dataset_rank(d) == 2, self%where('box/edges/value')// &
                   ': wrong shape (expected [frames][dimension])')) return
        call h5_dataset_dims(st, d, dims)
        if (failed(st, int(dims(1)) == Dm, self%where('box/edges/value')// &
                   ': wrong shape (the box dimension differs from that of the particle data)')) return
        if (failed(st, dims(2) >= 1, self%where('box/edges/value')//': no frames')) return
        if (failed(st, int(dims(2), i8) <= file_bytes(self%path), self%where('box/edges/value')// &
                   ': declares more frames than the file can hold (damaged or not written in full?)')) return
        allocate (series(Dm, dims(2)))
        call h5_read_whole(st, d, H5T_NATIVE_DOUBLE, c_loc(series), 'box/edges/value')
        if (failed(st, st%ok, self%where('box/edges/value')//': cannot read')) return
        call h5dclose_f(d, err)
        deallocate (self%edges)
        allocate (self%edges(3, dims(2)))
        self%edges = 0
        self%edges(1:Dm, :) = series
        self%box_series = .true.
        call read_box_steps(self, ename, dims(2))
        k = el_position
        if (.not. self%el(k)%present) k = el_velocity
        self%box_element = k
        write (s1, '(i0)') dims(2); write (s2, '(i0)') self%el(k)%nframes
        if (failed(st, int(dims(2), i8) == self%el(k)%nframes .or. dims(2) == 1 .or. &
                   (allocated(self%box_step) .and. self%el(k)%has_step), self%where('box/edges/value')// &
                   ': wrong shape ('//trim(s1)//' frames, '//trim(el_name(k))//'/value has '//trim(s2)// &
                   ')')) return
    end subroutine read_edges_series

    !> The boxes' own steps (ename/step, nframes of them), to match a series of another length to
    !> the frames; left unallocated when they are not there or not readable.
    subroutine read_box_steps(self, ename, nframes)
        class(h5md_trajectory_t), intent(inout) :: self
        character(len=*), intent(in) :: ename
        integer(hsize_t), intent(in) :: nframes
        integer(i8), allocatable, target :: steps(:)
        type(h5_status_t) :: lenient
        integer(hsize_t) :: sdims(1)
        integer(hid_t) :: d
        integer :: err
        if (.not. h5_link_exists(self%file, ename//'/step')) return
        call h5dopen_f(self%file, ename//'/step', d, err)
        if (err < 0) return
        if (h5_dataset_rank(d) == 1) then
            call h5_dataset_dims(lenient, d, sdims)
            if (sdims(1) == nframes) then
                allocate (steps(nframes))
                call h5_read_whole(lenient, d, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(steps), 'box/edges/step')
                if (lenient%ok) call move_alloc(steps, self%box_step)
            end if
        end if
        call h5dclose_f(d, err)
    end subroutine read_box_steps

    !> Atoms a0+1 .. a0+na (a0 0-based) of the time-independent per-atom dataset `name` (id,
    !> species, mass): into ints (int), longs (int64) or reals.
    subroutine read_atom_constant(self, st, name, a0, na, ints, longs, reals)
        class(h5md_trajectory_t), intent(inout) :: self
        type(h5_status_t), intent(inout) :: st
        character(len=*), intent(in) :: name
        integer(i8), intent(in) :: a0, na
        integer, intent(inout), target, optional :: ints(:)
        integer(i8), intent(inout), target, optional :: longs(:)
        real(dp), intent(inout), target, optional :: reals(:)
        integer(hid_t) :: d
        integer :: err
        integer(hsize_t) :: dims(1)
        if (na <= 0) return
        call h5dopen_f(self%file, self%group//'/'//name, d, err)
        if (failed(st, err >= 0, self%where(name)//': cannot open the dataset')) return
        if (failed(st, h5_dataset_rank(d) == 1, self%where(name)// &
                   ': wrong shape (expected one value per atom, time-independent)')) return
        call h5_dataset_dims(st, d, dims)
        if (failed(st, int(dims(1), i8) == self%natoms, self%where(name)// &
                   ': wrong shape (expected one value per atom, time-independent)')) return
        if (present(ints)) call h5_read_slab(st, d, H5T_NATIVE_INTEGER, c_loc(ints), [int(a0, hsize_t)], &
                                             [int(na, hsize_t)], na > 0)
        if (present(longs)) call h5_read_slab(st, d, h5kind_to_type(i8, H5_INTEGER_KIND), c_loc(longs), &
                                              [int(a0, hsize_t)], [int(na, hsize_t)], na > 0)
        if (present(reals)) call h5_read_slab(st, d, H5T_NATIVE_DOUBLE, c_loc(reals), [int(a0, hsize_t)], &
                                              [int(na, hsize_t)], na > 0)
        if (failed(st, st%ok, self%where(name)//': cannot read')) return
        call h5dclose_f(d, err)
    end subroutine read_atom_constant

    logical function traj_has(self, e)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        traj_has = self%el(e)%present
    end function traj_has

    integer(i8) function traj_frames(self, e)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        traj_frames = self%el(e)%nframes
    end function traj_frames

    !> Time of frame k (1-based) of element e; the frame index when the file has no time.
    real(dp) function traj_time_of(self, e, k) result(t)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: k
        if (self%el(e)%has_time) then
            t = self%el(e)%time(k)
        else
            t = real(k - 1, dp)
        end if
    end function traj_time_of

    !> The (uniform) time between the selected frames f0+1, f0+1+stride, ... (nsel of them) of
    !> element e; stops every rank when the file has no times or they are not equally spaced
    !> (`why` says which analysis needs them).
    real(dp) function traj_time_step(self, e, f0, nsel, stride, why) result(dt)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: f0, nsel, stride
        character(len=*), intent(in) :: why
        integer(i8) :: k
        real(dp) :: step, tol
        logical :: uniform, increasing
        call check_all(self%el(e)%has_time, self%where(trim(el_name(e))//'/time')//': missing ('//why// &
                       ' needs the time of every frame)')
        call check_all(nsel >= 2, self%where(trim(el_name(e))//'/value')//': too few frames selected ('//why// &
                       ' needs at least 2; see &analysis first_frame, last_frame, frame_stride)')
        dt = self%el(e)%time(f0 + 1 + stride) - self%el(e)%time(f0 + 1)
        tol = 1.0e-6_dp*abs(dt)
        increasing = .true.
        uniform = .true.
        do k = 1, nsel - 1
            step = self%el(e)%time(f0 + 1 + k*stride) - self%el(e)%time(f0 + 1 + (k - 1)*stride)
            ! (a NaN or infinite time fails both tests, found without an ordered comparison with a NaN,
            ! which a Debug build traps)
            if (.not. ieee_is_finite(step)) then
                increasing = .false.; uniform = .false.
                cycle
            end if
            if (.not. (step > 0)) increasing = .false.
            if (.not. ieee_is_finite(dt)) then      ! (the first step: already found not finite)
                uniform = .false.
            else if (.not. (abs(step - dt) <= tol)) then
                uniform = .false.
            end if
        end do
        call check_all(increasing, self%where(trim(el_name(e))//'/time')//': the times of the selected frames '// &
                       'do not increase (or are not finite numbers): a damaged or concatenated trajectory ('//why// &
                       ' needs increasing, equally spaced times)')
        call check_all(uniform, self%where(trim(el_name(e))//'/time')//': the selected frames are not equally '// &
                       'spaced in time ('//why//' needs a uniform sampling)')
    end function traj_time_step

    !> Box edges (3) at frame k (1-based) of the particle elements (zero where there is no edge):
    !> the box of the same row when the series has one per frame, else the last box whose step is
    !> not after the frame's (the first box when every box is later).
    function traj_box_edges(self, k) result(edges)
        class(h5md_trajectory_t), intent(in) :: self
        integer(i8), intent(in) :: k
        real(dp) :: edges(3)
        integer :: j, row
        if (.not. self%box_series .or. size(self%edges, 2) == 1) then
            edges = self%edges(:, 1)
        else if (int(size(self%edges, 2), i8) == self%el(self%box_element)%nframes) then
            edges = self%edges(:, k)
        else
            row = 1
            do j = 1, size(self%box_step)
                if (self%box_step(j) <= self%el(self%box_element)%step(k)) row = j
            end do
            edges = self%edges(:, row)
        end if
    end function traj_box_edges

    !> buf(1:D, 1:na, 1:nf) = element e, atoms a0+1..a0+na (a0 0-based), frames f0+1, f0+1+stride, ...
    !> (nf of them; f0 0-based); buf is real(dp) (read_real) or integer (read_int). Independent
    !> read (any rank, any pattern).
    !> Reads go in batches of at most frames_per_read frames: one HDF5 read over very many chunks
    !> (Terrace writes one chunk per frame) makes HDF5 hold a selection per chunk, about 7 KiB each.
    subroutine traj_read(self, e, f0, nf, stride, a0, na, buf)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: f0, nf, stride, a0, na
        class(*), intent(inout), target, contiguous :: buf(:, :, :)
        integer(i8) :: k, nk
        integer(hid_t) :: memtype
        type(c_ptr) :: p
        if (nf <= 0 .or. na <= 0) return
        do k = 1, nf, frames_per_read
            nk = min(frames_per_read, nf - k + 1)
            select type (buf)
            type is (real(dp))
                memtype = H5T_NATIVE_DOUBLE; p = c_loc(buf(1, 1, k))
            type is (integer)
                memtype = H5T_NATIVE_INTEGER; p = c_loc(buf(1, 1, k))
            class default
                error stop 'terrace_h5md_reader: read: the buffer is neither real(dp) nor integer'
            end select
            call read_block(self, e, f0 + (k - 1)*stride, nk, stride, a0, na, memtype, p, &
                            size(buf(:, :, k:k + nk - 1), kind=i8))
        end do
    end subroutine traj_read

    subroutine read_block(self, e, f0, nf, stride, a0, na, memtype, p, capacity, status)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: f0, nf, stride, a0, na, capacity
        integer(hid_t), intent(in) :: memtype
        type(c_ptr), intent(in) :: p
        type(h5_status_t), intent(inout), optional :: status
        type(h5_status_t) :: st
        integer(hsize_t) :: count(3), start(3), strides(3)
        if (nf <= 0 .or. na <= 0) return
        if (capacity < int(self%dimension, i8)*na*nf .or. f0 + (nf - 1)*stride >= self%el(e)%nframes .or. &
            a0 + na > self%natoms) then
            ! a programming error, not bad input
            error stop 'terrace_h5md_reader: read_block: selection outside the dataset or the buffer'
        end if
        start = [0_hsize_t, int(a0, hsize_t), int(f0, hsize_t)]
        count = [int(self%dimension, hsize_t), int(na, hsize_t), int(nf, hsize_t)]
        strides = [1_hsize_t, 1_hsize_t, int(max(stride, 1_i8), hsize_t)]
        call h5_read_slab(st, self%el(e)%value, memtype, p, start, count, .true., stride=strides)
        ! positions and velocities must be finite: a NaN is the file's fault, named as such
        if (st%ok .and. memtype == H5T_NATIVE_DOUBLE) call check_finite()
        if (present(status)) then
            if (.not. st%ok) call status%fail(self%where(trim(el_name(e))//'/value')//': read failed')
        else if (.not. st%ok) then
            ! a file truncated or corrupted after opening: only this rank may see it
            write (*, '(a)') 'terrace: error: '//self%where(trim(el_name(e))//'/value')//': read failed'
            error stop 1
        end if

    contains

        subroutine check_finite()
            real(dp), pointer :: r(:, :, :)
            integer(i8) :: j, a
            character(len=64) :: where
            character(len=:), allocatable :: what
            call c_f_pointer(p, r, [int(self%dimension, i8), na, nf])
            if (all(in_limit(r))) return
            do j = 1, nf
                do a = 1, na
                    if (all(in_limit(r(:, a, j)))) cycle
                    write (where, '(a,i0,a,i0)') 'frame ', f0 + (j - 1)*stride + 1, ', atom row ', a0 + a
                    if (all(ieee_is_finite(r(:, a, j)))) then
                        what = 'a value beyond 1e9 in magnitude (allowed: |value| <= 1e9 in the file''s units)'
                    else
                        what = 'NaN or infinite value in the file'
                    end if
                    if (present(status)) then
                        call status%fail(self%where(trim(el_name(e))//'/value')//': '//trim(where)//': '//what)
                    else
                        call abort_all(self%where(trim(el_name(e))//'/value')//': '//trim(where)//': '//what)
                    end if
                    return
                end do
            end do
        end subroutine check_finite

        !> Finite and within value_limit, tested without comparing a NaN (an ordered comparison with
        !> one raises the invalid exception, which a Debug build traps)
        elemental logical function in_limit(v)
            real(dp), intent(in) :: v
            in_limit = .false.
            if (ieee_is_finite(v)) in_limit = abs(v) <= value_limit
        end function in_limit

    end subroutine read_block

    subroutine traj_close(self)
        class(h5md_trajectory_t), intent(inout) :: self
        integer :: err, e
        do e = 1, 3
            if (self%el(e)%value >= 0) call h5dclose_f(self%el(e)%value, err)
            self%el(e)%value = -1
        end do
        if (self%file >= 0) call h5fclose_f(self%file, err)
        self%file = -1
    end subroutine traj_close

    ! ============================================================== the engine's start

    !> Read frame `frame` of an H5MD file (1..nframes; -1 is the last frame, -2 the one before, ...),
    !> for instance to start a run from it, into fr (see h5md_frame_t). Collective over comm (ok and
    !> msg are the same on every rank). Each rank receives a contiguous block of ids (a block
    !> distribution of 1..natoms over the ranks, in id order); the caller then moves the atoms to
    !> their domains.
    subroutine h5md_read_frame(path, comm, frame, fr, ok, msg)
        character(len=*), intent(in) :: path
        type(MPI_Comm), intent(in) :: comm
        integer(i8), intent(in) :: frame
        type(h5md_frame_t), intent(out) :: fr
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(h5md_trajectory_t) :: traj
        type(h5_status_t) :: st
        integer(i8) :: nf
        logical :: opened, hv, hi

        allocate (fr%ids(0), fr%types(0), fr%x(3, 0), fr%v(3, 0), fr%image(3, 0))
        hv = .false.; hi = .false.
        call traj%open(path, 'all', .true., .false., 'the frame to start from', '', ok=opened, msg=st%msg, &
                       constants=.false., key='read_h5md')
        st%ok = opened
        if (st%ok) then
            fr%dimension = traj%dimension; fr%natoms = traj%natoms
            call check_frame(traj, st, path, frame, nf, hv, hi)
        end if
        if (st%ok) call read_frame_block(traj, st, comm, merge(frame, nf + 1 + frame, frame > 0), hv, hi, fr)
        call traj%close()
        fr%has_velocity = hv .and. st%ok
        fr%has_image = hi .and. st%ok
        call h5_agree(comm, st, ok, msg)
        if (.not. ok) then
            ! messages that name the file already (traj%where) lose it: the caller names it
            if (index(msg, trim(path)//': read_h5md: ') == 1) then
                msg = msg(len_trim(path) + 14:)
            else if (index(msg, trim(path)//': ') == 1) then
                msg = msg(len_trim(path) + 3:)
            else
                msg = 'h5md: '//trim(path)//': '//trim(msg)
            end if
        end if
    end subroutine h5md_read_frame

    !> The frame asked for is in the file (nf frames), with a step; hv, hi: the file has velocities
    !> (as many frames as positions) and images.
    subroutine check_frame(traj, st, path, frame, nf, hv, hi)
        type(h5md_trajectory_t), intent(in) :: traj
        type(h5_status_t), intent(inout) :: st
        character(len=*), intent(in) :: path
        integer(i8), intent(in) :: frame
        integer(i8), intent(out) :: nf
        logical, intent(out) :: hv, hi
        character(len=24) :: fa, fb
        nf = traj%frames(el_position)
        if (nf == 0) then
            call st%fail('the file has no frames')
        else if (frame == 0 .or. frame > nf .or. frame < -nf) then
            write (fa, '(i0)') frame; write (fb, '(i0)') nf
            call st%fail(trim(path)//': h5md_frame = '//trim(fa)//': the file has '//trim(fb)//' frames (allowed: 1..'// &
                         trim(fb)//', or -1..-'//trim(fb)//' counting back from the last)')
        end if
        hv = traj%has(el_velocity)
        if (st%ok .and. hv) then
            if (traj%frames(el_velocity) /= nf) call st%fail(traj%where('velocity/value')// &
                                                             ' does not have the shape of position/value')
        end if
        hi = traj%has(el_image)
        if (st%ok .and. .not. traj%el(el_position)%has_step) &
            call st%fail(traj%where('position/step')//': missing or not one step per frame')
    end subroutine check_frame

    !> This rank's block of ids of frame fr_no (1-based): positions, and velocities (hv) and images
    !> (hi) when the file has them; ids, species, step, time and the box edges.
    subroutine read_frame_block(traj, st, comm, fr_no, hv, hi, fr)
        type(h5md_trajectory_t), intent(inout) :: traj
        type(h5_status_t), intent(inout) :: st
        type(MPI_Comm), intent(in) :: comm
        integer(i8), intent(in) :: fr_no
        logical, intent(in) :: hv, hi
        type(h5md_frame_t), intent(inout) :: fr
        real(dp), allocatable, target :: rbuf(:, :, :)
        integer, allocatable, target :: ibuf(:, :, :)
        integer(i8) :: first, nmine
        integer :: rank, nprocs, k, D_
        call MPI_Comm_rank(comm, rank)
        call MPI_Comm_size(comm, nprocs)
        D_ = fr%dimension
        call id_block(fr%natoms, nprocs, rank, first, nmine)
        deallocate (fr%ids, fr%types, fr%x, fr%v, fr%image)
        allocate (fr%ids(nmine), fr%types(nmine), fr%x(3, nmine), fr%v(3, nmine), fr%image(3, nmine))
        fr%x = 0; fr%v = 0; fr%image = 0; fr%types = 1
        allocate (rbuf(D_, max(nmine, 1_i8), 1), ibuf(D_, max(nmine, 1_i8), 1))
        call read_block(traj, el_position, fr_no - 1, 1_i8, 1_i8, first - 1, nmine, H5T_NATIVE_DOUBLE, c_loc(rbuf), &
                        size(rbuf, kind=i8), st)
        if (nmine > 0) fr%x(1:D_, :) = rbuf(:, 1:nmine, 1)
        if (hv) then
            call read_block(traj, el_velocity, fr_no - 1, 1_i8, 1_i8, first - 1, nmine, H5T_NATIVE_DOUBLE, &
                            c_loc(rbuf), size(rbuf, kind=i8), st)
            if (nmine > 0) fr%v(1:D_, :) = rbuf(:, 1:nmine, 1)
        end if
        if (hi) then
            call read_block(traj, el_image, fr_no - 1, 1_i8, 1_i8, first - 1, nmine, H5T_NATIVE_INTEGER, &
                            c_loc(ibuf), size(ibuf, kind=i8), st)
            if (nmine > 0) fr%image(1:D_, :) = ibuf(:, 1:nmine, 1)
        end if
        fr%step = traj%el(el_position)%step(fr_no)
        if (traj%el(el_position)%has_time) fr%time = traj%el(el_position)%time(fr_no)
        do k = 1, int(nmine)
            fr%ids(k) = first + k - 1
        end do
        if (h5_link_exists(traj%file, traj%group//'/id')) &
            call read_atom_constant(traj, st, 'id', first - 1, nmine, longs=fr%ids)
        if (h5_link_exists(traj%file, traj%group//'/species')) &
            call read_atom_constant(traj, st, 'species', first - 1, nmine, ints=fr%types)
        fr%edges = traj%box_edges(fr_no)
    end subroutine read_frame_block

end module terrace_h5md_reader
