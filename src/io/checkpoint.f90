!> Checkpoints: everything a run needs to continue bitwise, in one HDF5 file.
!>
!> Layout (h5py shapes; N atoms, rows in global id order):
!>
!>     /            attrs: format = 'terrace-checkpoint', format_version, terrace_version, deck,
!>                         deck_hash, integrator, natoms, nprocs, dimension
!>     /atoms/id          int64[N]      /atoms/type      int32[N]
!>     /atoms/position    float64[N][3] /atoms/velocity  float64[N][3]   /atoms/force  float64[N][3]
!>     /atoms/image       int32[N][3]   /atoms/slot      int64[N][2]     (rank, local index)
!>     /state       attrs: one scalar per quantity (int64 or float64): step, time, box_lo_1..3,
!>                         box_hi_1..3, mass_1..ntypes, output counters, integrator state
!>
!> Integrity (format_version 2): every /atoms dataset has an int64 attribute `checksum`, the
!> order-independent sum of terrace_checksum over its rows (the same on any rank count), and the
!> root attribute `state_checksum` covers natoms, nprocs, dimension, deck_hash and every /state
!> value (name and bits). A restart recomputes them all and refuses a checkpoint where one differs
!> (a damaged byte), then range-checks what it read (finite reals, types, slots). HDF5's own
!> metadata (superblock v2, object headers v2, written with libver 1.8 bounds) carries HDF5's
!> checksums, so a damaged header fails on open.
!>
!> Written collectively with parallel HDF5: every atom's row goes to the rank whose id block holds
!> it (terrace_id_blocks), which writes its block as one hyperslab; the scalars are the same on
!> every rank. The file is written as <path>.tmp and renamed to <path> by rank 0 after the
!> collective close, so a crash leaves the previous checkpoint intact. `slot` records where each
!> atom lived (rank and position in that rank's arrays): a restart on the same number of ranks puts
!> every atom back in its slot, so that sums run in the same order as in the uninterrupted run.
!> Reading: every rank opens the file read-only and reads it whole (O(N) memory per rank).
module terrace_checkpoint
    use, intrinsic :: iso_c_binding, only: c_loc, c_int, c_char, c_null_char, c_ptr
    use, intrinsic :: iso_fortran_env, only: int32
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_named_values, only: named_values_t
    use terrace_mpi_env, only: world, any_all
    use terrace_id_blocks, only: to_id_blocks
    use terrace_errors, only: note_broken_hdf5_file
    use terrace_file_ops, only: remove_file, remove_at_exit, keep_at_exit, output_target
    use terrace_checksum, only: checksum_rows, checksum_text, checksum_add, checksum_over_ranks
    use terrace_hdf5_io, only: h5_status_t, h5_agree, h5_writer_closed, h5_guard_begin, h5_guard_end, h5_section_begin, &
                               h5_section_end, h5_open_file, h5_create, h5_read, h5_transfer_list, h5_make_fixed, &
                               h5_write_slab, h5_dataset_rank, h5_dataset_dims, h5_read_whole, h5_attr_text, &
                               h5_attr_scalar, h5_read_attr_scalar, h5_read_attr_string
    use mpi_f08, only: MPI_Barrier
    use hdf5, only: hid_t, hsize_t, size_t, h5gcreate_f, h5gclose_f, h5gopen_f, h5dopen_f, h5dclose_f, h5fclose_f, &
                    h5pclose_f, h5aget_num_attrs_f, h5aexists_f, h5aopen_by_idx_f, h5aget_name_f, h5aget_type_f, h5tget_class_f, &
                    h5aread_f, h5tclose_f, h5aclose_f, h5kind_to_type, H5_INTEGER_KIND, H5_INDEX_NAME_F, &
                    H5_ITER_INC_F, H5T_INTEGER_F, H5T_NATIVE_DOUBLE, H5T_STD_I64LE, H5T_STD_I32LE, H5T_IEEE_F64LE
    implicit none
    private

    character(len=*), parameter :: format_name = 'terrace-checkpoint'
    integer, parameter :: format_version = 2
    integer, parameter :: ncol = 15           !< type, x(3), v(3), f(3), image(3), slot rank, slot index


    !> What a checkpoint holds, as read (every rank holds all of it, rows in id order).
    type, public :: ckpt_data_t
        integer(i8) :: natoms = 0, deck_hash = 0
        integer :: nprocs = 0, dimension = 3
        integer(i8), allocatable :: id(:), slot(:, :)
        integer, allocatable :: type(:), image(:, :)
        real(dp), allocatable :: x(:, :), v(:, :), f(:, :)
        type(named_values_t) :: values
    end type ckpt_data_t

    interface
        integer(c_int) function c_rename(old, new) bind(C, name='rename')
            import :: c_int, c_char
            character(kind=c_char), intent(in) :: old(*), new(*)
        end function c_rename
    end interface

    public :: write_checkpoint, read_checkpoint, probe_checkpoint_path

contains

    ! ------------------------------------------------------------------ named values


    ! ------------------------------------------------------------------ identity

    !> Can <path>.tmp be created (and <path> later replace it)? Rank 0 tries, the answer is shared.
    subroutine probe_checkpoint_path(path, ok, msg)
        character(len=*), intent(in) :: path
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: unit, ios
        logical :: failed
        ok = .true.; msg = ''
        if (world%rank == 0) then
            open (newunit=unit, file=output_target(path)//'.tmp', status='replace', action='write', iostat=ios, iomsg=msg)
            if (ios == 0) close (unit, status='delete')
            ok = ios == 0
        end if
        failed = .not. ok
        call any_all(failed)
        ok = .not. failed
        if (.not. ok) msg = 'cannot create '//output_target(path)//'.tmp (is the directory there and writable?)'
    end subroutine probe_checkpoint_path

    !> Checksum of the scalars: natoms, nprocs, dimension, deck hash and every named value (name and
    !> bits), independent of the order of the values.
    integer(i8) function state_checksum(natoms, nprocs, dimension, hash, values) result(h)
        integer(i8), intent(in) :: natoms, nprocs, dimension, hash
        type(named_values_t), intent(in) :: values
        character(len=8) :: bits
        integer :: k
        h = checksum_text(1_i8, transfer(natoms, bits)//transfer(nprocs, bits)//transfer(dimension, bits)// &
                          transfer(hash, bits))
        do k = 1, values%n
            if (values%is_int(k)) then
                bits = transfer(values%ival(k), bits)
            else
                bits = transfer(values%rval(k), bits)
            end if
            h = checksum_add(h, checksum_text(merge(2_i8, 3_i8, values%is_int(k)), trim(values%names(k))//'='//bits))
        end do
    end function state_checksum

    ! ------------------------------------------------------------------ writing

    !> Write the checkpoint of the owned atoms and the named values. Collective; ok is the same on
    !> every rank. The previous checkpoint at `path` is replaced only once the new one is complete.
    subroutine write_checkpoint(path, atoms, natoms, dimension, integrator, deck, hash, version, values, ok, msg)
        character(len=*), intent(in) :: path, integrator, deck, version
        type(atoms_t), intent(in) :: atoms
        integer(i8), intent(in) :: natoms, hash
        integer, intent(in) :: dimension
        type(named_values_t), intent(in) :: values
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        real(dp), allocatable :: block(:, :)
        integer(i8) :: first, count
        integer(hid_t) :: dxpl, file
        integer :: err, k
        logical :: good, failed
        character(len=:), allocatable :: tmp, target
        type(h5_status_t) :: st

        ok = .true.; msg = ''
        target = output_target(path)       ! a symbolic link stays; its target is replaced
        tmp = target//'.tmp'
        call gather_id_blocks(atoms, natoms, first, count, block, good)
        if (.not. good) then
            ok = .false.; msg = 'checkpoint: the atom ids are not 1..N over the ranks'; return
        end if

        if (world%rank == 0) call remove_at_exit(tmp, always=.true.)
        ! one section of the I/O watchdog (terrace_hdf5_io), to the rename: a rank stuck in HDF5
        ! ends the job with one line, whichever rank it is (15 reals and integers per atom)
        call h5_section_begin(path//' (&output checkpoint_file; writing '//tmp//')', 'writing the checkpoint', &
                              bytes=120*natoms)
        call h5_open_file(st, tmp, h5_create, file, world%comm, label=path//' (&output checkpoint_file; writing '//tmp//')')
        failed = .not. st%ok .or. file < 0
        call any_all(failed)
        if (failed) then
            call h5_section_end(world%comm)
            if (world%rank == 0) k = remove_file(tmp)
            ok = .false.; msg = 'checkpoint: cannot create '//tmp; return
        end if
        call h5_transfer_list(st, .true., dxpl)

        call h5_attr_text(st, file, 'format', format_name)
        call h5_attr_scalar(st, file, 'format_version', int(format_version, i8))
        call h5_attr_text(st, file, 'terrace_version', version)
        call h5_attr_text(st, file, 'deck', deck)
        call h5_attr_scalar(st, file, 'deck_hash', hash)
        call h5_attr_text(st, file, 'integrator', integrator)
        call h5_attr_scalar(st, file, 'natoms', natoms)
        call h5_attr_scalar(st, file, 'nprocs', int(world%nprocs, i8))
        call h5_attr_scalar(st, file, 'dimension', int(dimension, i8))
        call write_atom_rows(st, file, dxpl, natoms, first, count, block)
        call write_state(st, file, values)
        call h5_attr_scalar(st, file, 'state_checksum', state_checksum(natoms, int(world%nprocs, i8), &
                            int(dimension, i8), hash, values))
        call h5pclose_f(dxpl, err)
        call h5_guard_begin('H5Fclose'); call h5fclose_f(file, err); call h5_guard_end()
        call st%check(err, 'H5Fclose')
        call h5_writer_closed()
        call replace_checkpoint(st, path, tmp, target, ok, msg)
    end subroutine write_checkpoint

    !> This rank's atoms as rows of ncol reals (type, x, v, f, image, slot rank and index), sent to
    !> the ranks whose id blocks hold them: block(:, 1:count) are the rows of ids first..; good is
    !> false when the ids are not 1..natoms over the ranks.
    subroutine gather_id_blocks(atoms, natoms, first, count, block, good)
        type(atoms_t), intent(in) :: atoms
        integer(i8), intent(in) :: natoms
        integer(i8), intent(out) :: first, count
        real(dp), allocatable, intent(out) :: block(:, :)
        logical, intent(out) :: good
        real(dp), allocatable :: mine(:, :)
        integer :: n, i
        n = atoms%nlocal
        allocate (mine(ncol, max(n, 1)))
        do i = 1, n
            mine(1, i) = real(atoms%type(i), dp)
            mine(2:4, i) = atoms%x(:, i)
            mine(5:7, i) = atoms%v(:, i)
            mine(8:10, i) = atoms%f(:, i)
            mine(11:13, i) = real(atoms%image(:, i), dp)
            mine(14, i) = real(world%rank, dp)
            mine(15, i) = real(i, dp)
        end do
        call to_id_blocks(natoms, n, atoms%id(1:n), mine(:, 1:n), first, count, block, good)
    end subroutine gather_id_blocks

    !> /atoms: this rank's block of rows (ids first .. first+count-1) of every dataset, each with
    !> its checksum.
    subroutine write_atom_rows(st, file, dxpl, natoms, first, count, block)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: file, dxpl
        integer(i8), intent(in) :: natoms, first, count
        real(dp), intent(in) :: block(:, :)
        integer(i8), allocatable, target :: ids(:), slots(:, :)
        integer(int32), allocatable, target :: types(:), images(:, :)
        real(dp), allocatable, target :: r3(:, :)
        integer(hid_t) :: g
        integer :: err, k
        call h5gcreate_f(file, 'atoms', g, err); call st%check(err, 'create atoms')
        allocate (ids(max(count, 1_i8)), slots(2, max(count, 1_i8)), types(max(count, 1_i8)), &
                  images(3, max(count, 1_i8)), r3(3, max(count, 1_i8)))
        do k = 1, int(count)
            ids(k) = first + k - 1
            types(k) = int(nint(block(1, k)), int32)
            images(:, k) = int(nint(block(11:13, k)), int32)
            slots(:, k) = nint(block(14:15, k), i8)
        end do
        call put_rows(g, 'id', H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), 0, 8, c_loc(ids))
        call put_rows(g, 'type', H5T_STD_I32LE, h5kind_to_type(int32, H5_INTEGER_KIND), 0, 4, c_loc(types))
        call put_rows(g, 'image', H5T_STD_I32LE, h5kind_to_type(int32, H5_INTEGER_KIND), 3, 4, c_loc(images))
        call put_rows(g, 'slot', H5T_STD_I64LE, h5kind_to_type(i8, H5_INTEGER_KIND), 2, 8, c_loc(slots))
        r3 = block(2:4, 1:max(count, 1_i8))
        call put_rows(g, 'position', H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, 8, c_loc(r3))
        r3 = block(5:7, 1:max(count, 1_i8))
        call put_rows(g, 'velocity', H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, 8, c_loc(r3))
        r3 = block(8:10, 1:max(count, 1_i8))
        call put_rows(g, 'force', H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, 3, 8, c_loc(r3))
        call h5gclose_f(g, err)

    contains

        !> Dataset name of shape [N] (inner = 0) or [N][inner]; this rank writes its block of rows.
        subroutine put_rows(loc, name, ftype, mtype, inner, elsize, buf)
            integer(hid_t), intent(in) :: loc, ftype, mtype
            character(len=*), intent(in) :: name
            integer, intent(in) :: inner, elsize
            type(c_ptr), intent(in) :: buf
            integer(hid_t) :: d
            integer(hsize_t) :: nn, f0, c
            integer(i8) :: partial
            nn = int(natoms, hsize_t); f0 = int(first - 1, hsize_t); c = int(count, hsize_t)
            if (inner == 0) then
                call h5_make_fixed(st, loc, name, ftype, [nn], d)
                call h5_write_slab(st, d, mtype, buf, [f0], [c], count > 0, dxpl)
            else
                call h5_make_fixed(st, loc, name, ftype, [int(inner, hsize_t), nn], d)
                call h5_write_slab(st, d, mtype, buf, [0_hsize_t, f0], [int(inner, hsize_t), c], count > 0, dxpl)
            end if
            partial = 0
            if (count > 0) partial = checksum_rows(first, count, max(inner, 1), elsize, buf)
            call h5_attr_scalar(st, d, 'checksum', checksum_over_ranks(partial))
            call h5dclose_f(d, err)
        end subroutine put_rows

    end subroutine write_atom_rows

    !> /state: one scalar attribute per named value.
    subroutine write_state(st, file, values)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: file
        type(named_values_t), intent(in) :: values
        integer(hid_t) :: gs
        integer :: err, k
        call h5gcreate_f(file, 'state', gs, err); call st%check(err, 'create state')
        do k = 1, values%n
            if (values%is_int(k)) then
                call h5_attr_scalar(st, gs, trim(values%names(k)), values%ival(k))
            else
                call h5_attr_scalar(st, gs, trim(values%names(k)), values%rval(k))
            end if
        end do
        call h5gclose_f(gs, err)
    end subroutine write_state

    !> After the collective close of tmp: if every rank wrote it whole, rank 0 renames it over
    !> target (the previous checkpoint); else it is removed and the previous checkpoint stays.
    subroutine replace_checkpoint(st, path, tmp, target, ok, msg)
        type(h5_status_t), intent(inout) :: st
        character(len=*), intent(in) :: path, tmp, target
        logical, intent(inout) :: ok
        character(len=*), intent(inout) :: msg
        logical :: good, failed
        integer :: k
        call h5_agree(world%comm, st, good, msg)
        failed = .not. good
        if (failed) then
            ! a full device: HDF5 cannot end cleanly (terrace_errors); the previous checkpoint stays
            call note_broken_hdf5_file()
            call h5_section_end(world%comm)
            if (world%rank == 0) k = remove_file(tmp)
            ok = .false.; msg = 'checkpoint: HDF5 failed while writing '//tmp//' (is the device full?)'; return
        end if
        ! the file is complete on disk: replace the previous checkpoint
        call MPI_Barrier(world%comm)
        if (world%rank == 0) then
            good = c_rename(tmp//c_null_char, target//c_null_char) == 0
            call keep_at_exit(tmp)
        end if
        failed = .not. good
        call any_all(failed)
        call h5_section_end(world%comm)
        if (failed) then
            ok = .false.; msg = 'checkpoint: cannot rename '//tmp//' to '//path
        end if
    end subroutine replace_checkpoint

    ! ------------------------------------------------------------------ reading

    !> Read a checkpoint (every rank reads all of it). ok is the same on every rank; msg says what
    !> is wrong (missing, not a checkpoint, damaged).
    subroutine read_checkpoint(path, data, ok, msg)
        character(len=*), intent(in) :: path
        type(ckpt_data_t), intent(out) :: data
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer(hid_t) :: file
        integer :: err
        type(h5_status_t) :: st
        integer(i8) :: v, stored

        ok = .true.; msg = ''
        call open_checkpoint(path, file, st, ok, msg)
        if (.not. ok) then
            call agree_fail(ok, msg); return
        end if
        v = 0
        call h5_read_attr_scalar(st, file, 'natoms', data%natoms)
        call h5_read_attr_scalar(st, file, 'nprocs', v); data%nprocs = int(v)
        call h5_read_attr_scalar(st, file, 'dimension', v); data%dimension = int(v)
        call h5_read_attr_scalar(st, file, 'deck_hash', data%deck_hash)
        ! the atom count must be the datasets' length before anything is allocated with it
        if (st%ok) call check_length(st, file, 'atoms/id', data%natoms)
        if (st%ok .and. data%natoms > 0) then
            call read_atom_rows(st, file, data)
        else
            call st%fail('natoms')
        end if
        call read_state(st, file, data%values)
        ! the scalars against their checksum, then the ranges of what was read
        if (st%ok) then
            stored = 0
            call h5_read_attr_scalar(st, file, 'state_checksum', stored)
            if (st%ok .and. stored /= state_checksum(data%natoms, int(data%nprocs, i8), int(data%dimension, i8), &
                                                     data%deck_hash, data%values)) &
                call st%fail('the scalars (natoms, nprocs, /state) do not match state_checksum')
        end if
        if (st%ok) call check_ranges(st, data)
        call h5fclose_f(file, err)
        if (.not. st%ok) then
            ok = .false.; msg = 'damaged checkpoint: '//trim(st%msg)
        end if
        call agree_fail(ok, msg)
    end subroutine read_checkpoint

    !> Open path read-only and check it is a checkpoint of this format version (ok false and msg
    !> why, the file closed, when not); st holds a failure to read the version.
    subroutine open_checkpoint(path, file, st, ok, msg)
        character(len=*), intent(in) :: path
        integer(hid_t), intent(out) :: file
        type(h5_status_t), intent(inout) :: st
        logical, intent(inout) :: ok
        character(len=*), intent(inout) :: msg
        character(len=64) :: fmt
        logical :: exists, have
        integer(i8) :: v
        integer :: err
        file = -1
        inquire (file=path, exist=exists)
        if (.not. exists) then
            ok = .false.; msg = 'no such file'; return
        end if
        call h5_open_file(st, path, h5_read, file)
        if (file < 0) then
            ok = .false.; msg = 'not an HDF5 file (damaged or not a checkpoint)'; return
        end if
        call h5_read_attr_string(file, 'format', fmt)
        if (fmt /= format_name) then
            ok = .false.; msg = 'not a Terrace checkpoint (no format = '''//format_name//''' attribute)'
            call h5aexists_f(file, 'format', have, err)
            if (err < 0) msg = 'damaged checkpoint: its root object header is unreadable (fails HDF5''s checksum)'
            call h5fclose_f(file, err); return
        end if
        v = 0
        call h5_read_attr_scalar(st, file, 'format_version', v)
        if (st%ok .and. v /= format_version) then
            ok = .false.
            write (msg, '(a,i0,a,i0,a)') 'checkpoint format_version ', v, ' (this Terrace reads version ', &
                format_version, ', with checksums): start the run again from its deck'
            call h5fclose_f(file, err)
        end if
    end subroutine open_checkpoint

    !> ok the same on every rank: a failure on one rank is 'unreadable on another rank' on the others.
    subroutine agree_fail(ok, msg)
        logical, intent(inout) :: ok
        character(len=*), intent(inout) :: msg
        logical :: failed
        failed = .not. ok
        call any_all(failed)
        if (failed .and. ok) then
            ok = .false.; msg = 'unreadable on another rank'
        end if
    end subroutine agree_fail

    !> Every /atoms dataset, whole, checked against its shape and checksum.
    subroutine read_atom_rows(st, file, data)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: file
        type(ckpt_data_t), intent(inout) :: data
        integer(i8), allocatable, target :: ids(:), slots(:, :)
        integer(int32), allocatable, target :: types(:), images(:, :)
        real(dp), allocatable, target :: r3(:, :)
        integer(hsize_t) :: nn
        nn = int(data%natoms, hsize_t)
        allocate (ids(nn), slots(2, nn), types(nn), images(3, nn), r3(3, nn))
        call get_rows(st, file, 'atoms/id', h5kind_to_type(i8, H5_INTEGER_KIND), [nn], 8, c_loc(ids))
        call get_rows(st, file, 'atoms/slot', h5kind_to_type(i8, H5_INTEGER_KIND), [2_hsize_t, nn], 8, c_loc(slots))
        call get_rows(st, file, 'atoms/type', h5kind_to_type(int32, H5_INTEGER_KIND), [nn], 4, c_loc(types))
        call get_rows(st, file, 'atoms/image', h5kind_to_type(int32, H5_INTEGER_KIND), [3_hsize_t, nn], 4, c_loc(images))
        data%id = ids; data%slot = slots; data%type = int(types); data%image = int(images)
        call get_rows(st, file, 'atoms/position', H5T_NATIVE_DOUBLE, [3_hsize_t, nn], 8, c_loc(r3)); data%x = r3
        call get_rows(st, file, 'atoms/velocity', H5T_NATIVE_DOUBLE, [3_hsize_t, nn], 8, c_loc(r3)); data%v = r3
        call get_rows(st, file, 'atoms/force', H5T_NATIVE_DOUBLE, [3_hsize_t, nn], 8, c_loc(r3)); data%f = r3
    end subroutine read_atom_rows

    !> The named values of /state: each attribute, int64 or float64.
    subroutine read_state(st, file, values)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: file
        type(named_values_t), intent(inout) :: values
        integer(hid_t) :: g, a, t
        integer :: err, k, na, cls
        integer(i8), target :: ibuf
        real(dp), target :: rbuf
        character(len=64) :: name
        integer(size_t) :: nlen
        type(c_ptr) :: pbuf
        call h5gopen_f(file, 'state', g, err); call st%check(err, 'open state')
        if (.not. st%ok) return
        call h5aget_num_attrs_f(g, na, err)
        do k = 0, na - 1
            call h5aopen_by_idx_f(g, '.', H5_INDEX_NAME_F, H5_ITER_INC_F, int(k, hsize_t), a, err)
            call st%check(err, 'reading /state (its header fails HDF5''s checksum?)')
            if (err < 0) exit
            nlen = len(name)
            name = ''
            call h5aget_name_f(a, nlen, name, err)
            call h5aget_type_f(a, t, err)
            call h5tget_class_f(t, cls, err)
            if (cls == H5T_INTEGER_F) then
                pbuf = c_loc(ibuf)
                call h5aread_f(a, h5kind_to_type(i8, H5_INTEGER_KIND), pbuf, err)
                call values%put(trim(name), ibuf)
            else
                pbuf = c_loc(rbuf)
                call h5aread_f(a, H5T_NATIVE_DOUBLE, pbuf, err)
                call values%put(trim(name), rbuf)
            end if
            call st%check(err, 'read a state attribute')
            call h5tclose_f(t, err)
            call h5aclose_f(a, err)
        end do
        call h5gclose_f(g, err)
    end subroutine read_state

    !> The ranges of what was read: ranks and dimension, types, finite reals, slots, /state values.
    subroutine check_ranges(st, data)
        type(h5_status_t), intent(inout) :: st
        type(ckpt_data_t), intent(in) :: data
        integer(i8) :: ntypes
        logical :: have
        integer :: k
        have = .true.
        ntypes = data%values%get_i('ntypes', have)
        if (data%nprocs < 1 .or. (data%dimension /= 2 .and. data%dimension /= 3)) then
            call st%fail('nprocs or dimension out of range')
        else if (any(data%type < 1) .or. (have .and. any(data%type > ntypes))) then
            call st%fail('an atom type outside 1..ntypes')
        else if (.not. (all(abs(data%x) <= huge(1.0_dp)) .and. all(abs(data%v) <= huge(1.0_dp)) .and. &
                        all(abs(data%f) <= huge(1.0_dp)))) then
            call st%fail('a position, velocity or force that is NaN or infinite')
        else if (any(data%slot(1, :) < 0) .or. any(data%slot(1, :) >= data%nprocs) .or. any(data%slot(2, :) < 1)) then
            call st%fail('an atom slot outside the ranks that wrote it')
        end if
        do k = 1, data%values%n
            if (.not. data%values%is_int(k)) then
                if (.not. abs(data%values%rval(k)) <= huge(1.0_dp)) &
                    call st%fail('/state '//trim(data%values%names(k))//' is NaN or infinite')
            end if
        end do
    end subroutine check_ranges

    !> natoms must be the length of dataset dname (one dimension) before it sizes any array.
    subroutine check_length(st, file, dname, natoms)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: file
        character(len=*), intent(in) :: dname
        integer(i8), intent(in) :: natoms
        integer(hid_t) :: d
        integer(hsize_t) :: fd(1)
        integer :: e
        call h5dopen_f(file, dname, d, e); call st%check(e, 'open '//dname)
        if (e < 0) return
        if (h5_dataset_rank(d) /= 1) call st%fail(dname//' has the wrong rank')
        if (st%ok) call h5_dataset_dims(st, d, fd)
        if (st%ok .and. fd(1) /= natoms) call st%fail('natoms differs from the length of '//dname)
        call h5dclose_f(d, e)
    end subroutine check_length

    !> The whole dataset dname, which must have the Fortran shape dims (elements of elsize
    !> bytes), and must match its checksum attribute.
    subroutine get_rows(st, file, dname, mtype, dims, elsize, buf)
        type(h5_status_t), intent(inout) :: st
        integer(hid_t), intent(in) :: file
        character(len=*), intent(in) :: dname
        integer(hid_t), intent(in) :: mtype
        integer(hsize_t), intent(in) :: dims(:)
        integer, intent(in) :: elsize
        type(c_ptr), intent(in) :: buf
        integer(hid_t) :: d
        integer(hsize_t) :: fd(size(dims))
        integer(i8) :: sum
        integer :: e
        if (.not. st%ok) return
        call h5dopen_f(file, dname, d, e); call st%check(e, 'open '//dname)
        if (e < 0) return
        if (h5_dataset_rank(d) /= size(dims)) call st%fail(dname//' has the wrong rank')
        if (st%ok) call h5_dataset_dims(st, d, fd)
        if (st%ok .and. any(fd /= dims)) call st%fail(dname//' has the wrong shape')
        if (st%ok) call h5_read_whole(st, d, mtype, buf, dname)
        sum = 0
        if (st%ok) call h5_read_attr_scalar(st, d, 'checksum', sum)
        if (st%ok) then
            if (sum /= checksum_rows(1_i8, int(dims(size(dims)), i8), int(product(dims(1:size(dims) - 1))), &
                                     elsize, buf)) call st%fail(dname//' does not match its checksum')
        end if
        call h5dclose_f(d, e)
    end subroutine get_rows

end module terrace_checkpoint
