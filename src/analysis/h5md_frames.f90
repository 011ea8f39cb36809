!> Reading frames of an H5MD trajectory for terrace-analyze (Terrace's own files and other H5MD
!> 1.0/1.1 writers).
!>
!> What is read (particles/<group>, group 'all' by default):
!>   position/value, velocity/value   Float[frames][N][D]   (Fortran: (D, N, frames))
!>   image/value                      Integer[frames][N][D] (optional; unwraps periodic positions)
!>   <element>/time                   a 1-D dataset of one time per frame, or a scalar dataset
!>                                    (time of frame k = offset + k * value, attribute `offset`
!>                                    optional) as H5MD allows for regularly sampled elements
!>   box                              attribute boundary ('periodic' | 'none', D strings, fixed- or
!>                                    variable-length), and edges: a time-independent dataset
!>                                    edges[D] (or a diagonal edges[D][D]), or a time-dependent
!>                                    element edges/value[frames][D] (one box per frame)
!>   species, mass                    Integer[N], Float[N] (optional)
!>   `unit` attributes of position/value and of the time (optional; used in the CSV headers)
!>
!> Every rank opens the file read-only with HDF5's default (POSIX) driver and reads its own
!> hyperslabs independently, so the analyses can split the work over frames (one frame, all atoms)
!> or over atoms (a block of atoms, all frames) in any pattern. Errors stop every rank through the
!> collective error path (every rank checks the same file) with the file and the object at fault.
module terrace_h5md_frames
    use, intrinsic :: iso_c_binding, only: c_ptr, c_loc, c_char, c_null_char, c_f_pointer, c_associated
    use terrace_kinds, only: dp, i8
    use terrace_errors, only: check_all
    use hdf5
    implicit none
    private

    integer, parameter, public :: el_position = 1, el_velocity = 2, el_image = 3
    character(len=8), parameter :: el_name(3) = [character(len=8) :: 'position', 'velocity', 'image']

    !> One time-dependent particle element.
    type :: element_t
        logical :: present = .false.
        integer(hid_t) :: value = -1
        integer(i8) :: nframes = 0
        real(dp), allocatable :: time(:)         !< time of each frame (empty if the file has none)
        logical :: has_time = .false.
    end type element_t

    type, public :: h5md_trajectory_t
        character(len=:), allocatable :: path
        character(len=:), allocatable :: group       !< '/particles/<name>'
        integer(hid_t) :: file = -1
        integer(i8) :: natoms = 0
        integer :: dimension = 0
        logical :: periodic(3) = .false.
        type(element_t) :: el(3)
        real(dp), allocatable :: edges(:, :)         !< (3, nbox): nbox = 1 for a fixed box
        logical :: box_series = .false.              !< edges given per frame (edges/value)
        logical :: has_box = .false.
        integer, allocatable :: species(:)
        real(dp), allocatable :: mass(:)
        character(len=32) :: unit_length = '', unit_time = '', unit_velocity = ''
    contains
        procedure :: open => traj_open
        procedure :: close => traj_close
        procedure :: has => traj_has
        procedure :: frames => traj_frames
        procedure :: time_of => traj_time_of
        procedure :: box_edges => traj_box_edges
        procedure :: read_real => traj_read_real
        procedure :: read_int => traj_read_int
        procedure :: where => traj_where
        procedure :: time_step => traj_time_step
    end type h5md_trajectory_t

    logical, save :: library_open = .false.
    integer(i8), parameter :: frames_per_read = 1024

    public :: atom_block

contains

    !> Block distribution of atoms 1..n over p ranks: rank r (0-based) takes atoms a0+1 .. a0+na.
    pure subroutine atom_block(n, p, r, a0, na)
        integer(i8), intent(in) :: n
        integer, intent(in) :: p, r
        integer(i8), intent(out) :: a0, na
        integer(i8) :: q, rm
        q = n/p; rm = mod(n, int(p, i8))
        na = q + merge(1_i8, 0_i8, r < rm)
        a0 = r*q + min(int(r, i8), rm)
    end subroutine atom_block

    !> "FILE: /particles/all/<what>" for messages.
    function traj_where(self, what) result(s)
        class(h5md_trajectory_t), intent(in) :: self
        character(len=*), intent(in) :: what
        character(len=:), allocatable :: s
        s = self%path//': '//self%group//'/'//what
    end function traj_where

    !> Open `path` and read everything small: shapes, times, box, species, masses. `group` is the
    !> particles group ('all'). need_velocity / need_position: the analyses asked for need them
    !> (their absence is an error naming the dataset and the reason `why_*`).
    subroutine traj_open(self, path, group, need_position, need_velocity, why_position, why_velocity)
        class(h5md_trajectory_t), intent(inout) :: self
        character(len=*), intent(in) :: path, group
        logical, intent(in) :: need_position, need_velocity
        character(len=*), intent(in) :: why_position, why_velocity
        integer :: err, e, k
        logical :: exists, ok
        integer(hsize_t) :: dims(3), ref(3)
        character(len=16) :: a, b

        self%path = trim(path)
        self%group = '/particles/'//trim(group)
        if (.not. library_open) then
            call h5open_f(err)
            call h5eset_auto_f(0, err)
            library_open = .true.
        end if
        inquire (file=self%path, exist=exists)
        call check_all(exists, self%path//': trajectory_file: cannot open (no such file)')
        call h5fopen_f(self%path, H5F_ACC_RDONLY_F, self%file, err)
        call check_all(err >= 0, self%path//': trajectory_file: cannot open as HDF5 (not an HDF5/H5MD file?)')
        call check_all(link_exists(self%file, self%group), self%path//': '//self%group// &
                       ': missing (no particles group of that name; set &analysis particles_group)')

        ! ---- the elements and their shapes
        ref = 0
        do e = 1, 3
            associate (el => self%el(e))
                el%present = link_exists(self%file, self%group//'/'//trim(el_name(e))//'/value')
                if (.not. el%present) cycle
                call h5dopen_f(self%file, self%group//'/'//trim(el_name(e))//'/value', el%value, err)
                call check_all(err >= 0, self%where(trim(el_name(e))//'/value')//': cannot open the dataset')
                call dims_of(el%value, 3, dims, ok)
                call check_all(ok, self%where(trim(el_name(e))//'/value')// &
                               ': wrong shape (expected [frames][atoms][dimension])')
                call check_all(dims(1) >= 1 .and. dims(1) <= 3 .and. dims(2) >= 1, &
                               self%where(trim(el_name(e))//'/value')//': wrong shape (dimension must be 1..3, '// &
                               'at least one atom)')
                if (all(ref == 0)) then
                    ref = dims
                else if (any(dims(1:2) /= ref(1:2))) then
                    write (a, '(i0,a,i0)') ref(2), ' x ', ref(1)
                    write (b, '(i0,a,i0)') dims(2), ' x ', dims(1)
                    call check_all(.false., self%where(trim(el_name(e))//'/value')//': wrong shape ('// &
                                   trim(b)//' atoms x dimension; the other elements have '//trim(a)//')')
                end if
                el%nframes = int(dims(3), i8)
                call read_times(self, e)
            end associate
        end do
        if (self%el(el_image)%present .and. self%el(el_position)%present) then
            write (a, '(i0)') self%el(el_position)%nframes
            write (b, '(i0)') self%el(el_image)%nframes
            call check_all(self%el(el_image)%nframes == self%el(el_position)%nframes, &
                           self%where('image/value')//': wrong shape ('//trim(b)//' frames, position/value has '// &
                           trim(a)//')')
        end if
        if (need_position) call check_all(self%el(el_position)%present, self%where('position/value')// &
                                          ': missing ('//why_position//')')
        if (need_velocity) call check_all(self%el(el_velocity)%present, self%where('velocity/value')// &
                                          ': missing ('//why_velocity//')')
        call check_all(any(self%el(:)%present), self%where('position/value')//': missing (no position or '// &
                       'velocity element: nothing to analyse)')
        self%dimension = int(ref(1))
        self%natoms = int(ref(2), i8)

        call read_box(self)

        ! ---- per-atom constants
        allocate (self%species(self%natoms), self%mass(self%natoms))
        self%species = 1; self%mass = 1
        if (link_exists(self%file, self%group//'/species')) &
            call read_atom_constant(self, 'species', ints=self%species)
        if (link_exists(self%file, self%group//'/mass')) &
            call read_atom_constant(self, 'mass', reals=self%mass)
        if (self%el(el_position)%present) then
            self%unit_length = string_attribute(self%el(el_position)%value, 'unit')
        end if
        if (self%el(el_velocity)%present) self%unit_velocity = string_attribute(self%el(el_velocity)%value, 'unit')
        do k = 1, 3
            if (len_trim(self%unit_time) > 0) exit
            if (self%el(k)%present) self%unit_time = time_unit(self, k)
        end do
    end subroutine traj_open

    !> The time of every frame of element e: a dataset time[frames], or a scalar time step with an
    !> optional offset attribute. Absent: has_time = .false.
    subroutine read_times(self, e)
        class(h5md_trajectory_t), intent(inout) :: self
        integer, intent(in) :: e
        integer(hid_t) :: d, sp, a
        integer :: err, rank
        integer(hsize_t) :: dims(1), maxdims(1)
        integer(i8) :: k
        real(dp), target :: scal(1), offset(1)
        real(dp), allocatable, target :: times(:)
        character(len=:), allocatable :: name
        character(len=16) :: s1, s2
        logical :: has_offset
        associate (el => self%el(e))
            name = self%group//'/'//trim(el_name(e))//'/time'
            allocate (el%time(0))
            if (.not. link_exists(self%file, name)) return
            call h5dopen_f(self%file, name, d, err)
            call check_all(err >= 0, self%where(trim(el_name(e))//'/time')//': cannot open the dataset')
            call h5dget_space_f(d, sp, err)
            call h5sget_simple_extent_ndims_f(sp, rank, err)
            if (rank == 0) then
                call dread(d, H5T_NATIVE_DOUBLE, c_loc(scal), err)
                call check_all(err >= 0, self%where(trim(el_name(e))//'/time')//': cannot read')
                offset = 0
                call h5aexists_f(d, 'offset', has_offset, err)
                if (has_offset) then
                    call h5aopen_f(d, 'offset', a, err)
                    call aread(a, H5T_NATIVE_DOUBLE, c_loc(offset), err)
                    call h5aclose_f(a, err)
                end if
                deallocate (el%time)
                allocate (el%time(el%nframes))
                do k = 1, el%nframes
                    el%time(k) = offset(1) + real(k - 1, dp)*scal(1)
                end do
            else
                call check_all(rank == 1, self%where(trim(el_name(e))//'/time')// &
                               ': wrong shape (expected time[frames] or a scalar time step)')
                call h5sget_simple_extent_dims_f(sp, dims, maxdims, err)
                write (s1, '(i0)') dims(1); write (s2, '(i0)') el%nframes
                call check_all(int(dims(1), i8) == el%nframes, self%where(trim(el_name(e))//'/time')// &
                               ': wrong shape ('//trim(s1)//' times for '//trim(s2)//' frames of '// &
                               trim(el_name(e))//'/value)')
                deallocate (el%time)
                allocate (times(el%nframes))
                if (el%nframes > 0) then
                    call dread(d, H5T_NATIVE_DOUBLE, c_loc(times), err)
                    call check_all(err >= 0, self%where(trim(el_name(e))//'/time')//': cannot read')
                end if
                call move_alloc(times, el%time)
            end if
            el%has_time = .true.
            call h5sclose_f(sp, err)
            call h5dclose_f(d, err)
        end associate
    end subroutine read_times

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
        u = string_attribute(d, 'unit')
        call h5dclose_f(d, err)
    end function time_unit

    !> The box: boundary attribute and edges (fixed dataset, diagonal matrix, or edges/value series).
    subroutine read_box(self)
        class(h5md_trajectory_t), intent(inout) :: self
        character(len=:), allocatable :: bname, ename
        character(len=32), allocatable :: boundary(:)
        integer(hid_t) :: g, d, sp
        integer :: err, rank, k, Dm
        integer(hsize_t) :: dims(2), maxdims(2)
        real(dp), allocatable, target :: m(:, :), series(:, :)
        logical :: is_group, ok
        character(len=16) :: s1, s2

        Dm = self%dimension
        allocate (self%edges(3, 1))
        self%edges = 0
        bname = self%group//'/box'
        self%has_box = link_exists(self%file, bname)
        if (.not. self%has_box) return
        call h5gopen_f(self%file, bname, g, err)
        call check_all(err >= 0, self%where('box')//': cannot open the group')
        call string_list_attribute(g, 'boundary', boundary, ok)
        ename = bname//'/edges'
        if (link_exists(self%file, ename)) then
            call h5dopen_f(self%file, ename, d, err)
            is_group = err < 0
            if (.not. is_group) then
                ! time-independent: edges[D] or edges[D][D]
                call h5dget_space_f(d, sp, err)
                call h5sget_simple_extent_ndims_f(sp, rank, err)
                call check_all(rank == 1 .or. rank == 2, self%where('box/edges')// &
                               ': wrong shape (expected edges[dimension] or edges[dimension][dimension])')
                call h5sget_simple_extent_dims_f(sp, dims(1:rank), maxdims(1:rank), err)
                call h5sclose_f(sp, err)
                call check_all(all(int(dims(1:rank)) == Dm), self%where('box/edges')// &
                               ': wrong shape (the box dimension differs from that of the particle data)')
                allocate (m(Dm, merge(Dm, 1, rank == 2)))
                call dread(d, H5T_NATIVE_DOUBLE, c_loc(m), err)
                call check_all(err >= 0, self%where('box/edges')//': cannot read')
                if (rank == 1) then
                    self%edges(1:Dm, 1) = m(:, 1)
                else
                    do k = 1, Dm
                        self%edges(k, 1) = m(k, k)
                        m(k, k) = 0
                    end do
                    call check_all(all(m == 0), self%where('box/edges')// &
                                   ': a triclinic box (off-diagonal edges) is not supported')
                end if
                call h5dclose_f(d, err)
            else
                ! time-dependent: edges/value[frames][D]
                call check_all(link_exists(self%file, ename//'/value'), self%where('box/edges/value')// &
                               ': missing (box/edges is a group, so it must be a time-dependent element)')
                call h5dopen_f(self%file, ename//'/value', d, err)
                call check_all(err >= 0, self%where('box/edges/value')//': cannot open the dataset')
                call h5dget_space_f(d, sp, err)
                call h5sget_simple_extent_ndims_f(sp, rank, err)
                call check_all(rank == 2, self%where('box/edges/value')//': wrong shape (expected [frames][dimension])')
                call h5sget_simple_extent_dims_f(sp, dims, maxdims, err)
                call h5sclose_f(sp, err)
                call check_all(int(dims(1)) == Dm, self%where('box/edges/value')// &
                               ': wrong shape (the box dimension differs from that of the particle data)')
                call check_all(dims(2) >= 1, self%where('box/edges/value')//': no frames')
                allocate (series(Dm, dims(2)))
                call dread(d, H5T_NATIVE_DOUBLE, c_loc(series), err)
                call check_all(err >= 0, self%where('box/edges/value')//': cannot read')
                call h5dclose_f(d, err)
                deallocate (self%edges)
                allocate (self%edges(3, dims(2)))
                self%edges = 0
                self%edges(1:Dm, :) = series
                self%box_series = .true.
                k = el_position
                if (.not. self%el(k)%present) k = el_velocity
                write (s1, '(i0)') dims(2); write (s2, '(i0)') self%el(k)%nframes
                call check_all(int(dims(2), i8) == self%el(k)%nframes .or. dims(2) == 1, &
                               self%where('box/edges/value')//': wrong shape ('//trim(s1)//' frames, '// &
                               trim(el_name(k))//'/value has '//trim(s2)//')')
            end if
        end if
        if (ok) then
            call check_all(size(boundary) == Dm, self%where('box')//': boundary attribute: wrong length '// &
                           '(one entry per dimension)')
            do k = 1, Dm
                select case (trim(boundary(k)))
                case ('periodic')
                    self%periodic(k) = .true.
                case ('none')
                case default
                    call check_all(.false., self%where('box')//": boundary attribute: unknown value '"// &
                                   trim(boundary(k))//"' (allowed: 'periodic', 'none')")
                end select
            end do
        else
            ! no boundary attribute: periodic where an edge is given
            self%periodic(1:Dm) = any(self%edges(1:Dm, :) > 0)
        end if
        do k = 1, Dm
            if (self%periodic(k)) call check_all(all(self%edges(k, :) > 0), self%where('box/edges')// &
                ': a periodic edge is missing or not positive')
        end do
        call h5gclose_f(g, err)
    end subroutine read_box

    subroutine read_atom_constant(self, name, ints, reals)
        class(h5md_trajectory_t), intent(inout) :: self
        character(len=*), intent(in) :: name
        integer, intent(inout), target, optional :: ints(:)
        real(dp), intent(inout), target, optional :: reals(:)
        integer(hid_t) :: d
        integer :: err
        integer(hsize_t) :: dims(1)
        logical :: ok
        call h5dopen_f(self%file, self%group//'/'//name, d, err)
        call check_all(err >= 0, self%where(name)//': cannot open the dataset')
        call dims_of(d, 1, dims, ok)
        call check_all(ok .and. int(dims(1), i8) == self%natoms, self%where(name)// &
                       ': wrong shape (expected one value per atom, time-independent)')
        if (present(ints)) call dread(d, H5T_NATIVE_INTEGER, c_loc(ints), err)
        if (present(reals)) call dread(d, H5T_NATIVE_DOUBLE, c_loc(reals), err)
        call check_all(err >= 0, self%where(name)//': cannot read')
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
        logical :: uniform
        call check_all(self%el(e)%has_time, self%where(trim(el_name(e))//'/time')//': missing ('//why// &
                       ' needs the time of every frame)')
        call check_all(nsel >= 2, self%where(trim(el_name(e))//'/value')//': too few frames selected ('//why// &
                       ' needs at least 2; see &analysis first_frame, last_frame, frame_stride)')
        dt = self%el(e)%time(f0 + 1 + stride) - self%el(e)%time(f0 + 1)
        tol = 1.0e-6_dp*abs(dt)
        uniform = dt > 0
        do k = 1, nsel - 1
            step = self%el(e)%time(f0 + 1 + k*stride) - self%el(e)%time(f0 + 1 + (k - 1)*stride)
            if (abs(step - dt) > tol) uniform = .false.
        end do
        call check_all(uniform, self%where(trim(el_name(e))//'/time')//': the selected frames are not equally '// &
                       'spaced in time ('//why//' needs a uniform sampling)')
    end function traj_time_step

    !> Box edges (3) at frame k (1-based) of the particle elements (zero where there is no edge).
    function traj_box_edges(self, k) result(edges)
        class(h5md_trajectory_t), intent(in) :: self
        integer(i8), intent(in) :: k
        real(dp) :: edges(3)
        if (self%box_series .and. size(self%edges, 2) > 1) then
            edges = self%edges(:, k)
        else
            edges = self%edges(:, 1)
        end if
    end function traj_box_edges

    !> buf(1:D, 1:na, 1:nf) = element e, atoms a0+1..a0+na (a0 0-based), frames f0+1, f0+1+stride, ...
    !> (nf of them; f0 0-based). Independent read (any rank, any pattern).
    !> Reads go in batches of at most frames_per_read frames: one HDF5 read over very many chunks
    !> (Terrace writes one chunk per frame) makes HDF5 hold a selection per chunk, about 7 KiB each.
    subroutine traj_read_real(self, e, f0, nf, stride, a0, na, buf)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: f0, nf, stride, a0, na
        real(dp), intent(inout), target, contiguous :: buf(:, :, :)
        integer(i8) :: k, nk
        if (nf <= 0 .or. na <= 0) return
        do k = 1, nf, frames_per_read
            nk = min(frames_per_read, nf - k + 1)
            call read_slab(self, e, f0 + (k - 1)*stride, nk, stride, a0, na, H5T_NATIVE_DOUBLE, c_loc(buf(1, 1, k)), &
                           size(buf(:, :, k:k + nk - 1), kind=i8))
        end do
    end subroutine traj_read_real

    subroutine traj_read_int(self, e, f0, nf, stride, a0, na, buf)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: f0, nf, stride, a0, na
        integer, intent(inout), target, contiguous :: buf(:, :, :)
        integer(i8) :: k, nk
        if (nf <= 0 .or. na <= 0) return
        do k = 1, nf, frames_per_read
            nk = min(frames_per_read, nf - k + 1)
            call read_slab(self, e, f0 + (k - 1)*stride, nk, stride, a0, na, H5T_NATIVE_INTEGER, c_loc(buf(1, 1, k)), &
                           size(buf(:, :, k:k + nk - 1), kind=i8))
        end do
    end subroutine traj_read_int

    subroutine read_slab(self, e, f0, nf, stride, a0, na, memtype, p, capacity)
        class(h5md_trajectory_t), intent(in) :: self
        integer, intent(in) :: e
        integer(i8), intent(in) :: f0, nf, stride, a0, na, capacity
        integer(hid_t), intent(in) :: memtype
        type(c_ptr), intent(in) :: p
        integer(hid_t) :: fsp, msp
        integer(hsize_t) :: count(3), start(3), strides(3)
        integer :: err, ios
        type(c_ptr) :: q
        if (nf <= 0 .or. na <= 0) return
        if (capacity < int(self%dimension, i8)*na*nf .or. f0 + (nf - 1)*stride >= self%el(e)%nframes .or. &
            a0 + na > self%natoms) then
            ! a programming error, not bad input
            error stop 'terrace_h5md_frames: read_slab: selection outside the dataset or the buffer'
        end if
        start = [0_hsize_t, int(a0, hsize_t), int(f0, hsize_t)]
        count = [int(self%dimension, hsize_t), int(na, hsize_t), int(nf, hsize_t)]
        strides = [1_hsize_t, 1_hsize_t, int(max(stride, 1_i8), hsize_t)]
        call h5dget_space_f(self%el(e)%value, fsp, err)
        call h5sselect_hyperslab_f(fsp, H5S_SELECT_SET_F, start, count, err, stride=strides)
        call h5screate_simple_f(3, count, msp, err)
        q = p
        call h5dread_f(self%el(e)%value, memtype, q, ios, mem_space_id=msp, file_space_id=fsp)
        call h5sclose_f(msp, err)
        call h5sclose_f(fsp, err)
        if (ios < 0) then
            ! a file truncated or corrupted after opening: only this rank may see it
            write (*, '(a)') 'terrace: error: '//self%where(trim(el_name(e))//'/value')//': read failed'
            error stop 1
        end if
    end subroutine read_slab

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

    ! ============================================================== helpers

    !> Does every component of the absolute path exist (links only; no error printed)?
    logical function link_exists(file, path) result(exists)
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
    end function link_exists

    !> Fortran-order dims of a dataset of the given rank; ok = .false. for another rank.
    subroutine dims_of(d, rank, dims, ok)
        integer(hid_t), intent(in) :: d
        integer, intent(in) :: rank
        integer(hsize_t), intent(out) :: dims(rank)
        logical, intent(out) :: ok
        integer(hid_t) :: sp
        integer(hsize_t) :: maxdims(rank)
        integer :: err, r
        dims = 0
        call h5dget_space_f(d, sp, err)
        call h5sget_simple_extent_ndims_f(sp, r, err)
        ok = r == rank
        if (ok) call h5sget_simple_extent_dims_f(sp, dims, maxdims, err)
        call h5sclose_f(sp, err)
    end subroutine dims_of

    !> Whole-dataset / whole-attribute reads through a pointer (HDF5 takes it as intent(inout)).
    subroutine dread(d, memtype, p, err)
        integer(hid_t), intent(in) :: d, memtype
        type(c_ptr), intent(in) :: p
        integer, intent(out) :: err
        type(c_ptr) :: q
        q = p
        call h5dread_f(d, memtype, q, err)
    end subroutine dread

    subroutine aread(a, memtype, p, err)
        integer(hid_t), intent(in) :: a, memtype
        type(c_ptr), intent(in) :: p
        integer, intent(out) :: err
        type(c_ptr) :: q
        q = p
        call h5aread_f(a, memtype, q, err)
    end subroutine aread

    !> A scalar string attribute (fixed or variable length); '' when absent or unreadable.
    function string_attribute(loc, name) result(s)
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        character(len=32) :: s
        character(len=32), allocatable :: list(:)
        logical :: ok
        s = ''
        call string_list_attribute(loc, name, list, ok)
        if (ok) then
            if (size(list) >= 1) s = list(1)
        end if
    end function string_attribute

    !> A string attribute (scalar or 1-D; fixed- or variable-length strings) as a list of strings.
    subroutine string_list_attribute(loc, name, list, ok)
        integer(hid_t), intent(in) :: loc
        character(len=*), intent(in) :: name
        character(len=32), allocatable, intent(out) :: list(:)
        logical, intent(out) :: ok
        integer(hid_t) :: a, ftype, mtype, sp
        integer(hssize_t) :: npoints
        integer(size_t) :: width
        integer :: err, i, j, n, tclass, cset
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
                    call c_f_pointer(ptrs(i), cs, [32])
                    do j = 1, 32
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
                    do j = 1, min(32, int(width))
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
    end subroutine string_list_attribute

end module terrace_h5md_frames
