!> File-system operations through a small C helper (file_ops.c): the absolute form of a path,
!> the kind of an existing path, atomic rename, advisory locks, and files removed at exit unless
!> committed. Used for the input and output checks made before a run writes anything.
module terrace_file_ops
    use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char
    implicit none
    private

    integer, parameter, public :: path_missing = 0, path_regular = 1, path_directory = 2, path_special = 3

    public :: resolve_path, path_kind, is_writable, rename_file, remove_file, lock_file, &
              remove_at_exit, keep_at_exit, process_id, directory_of, &
              temporary_name, commit_output, check_size, cleanup_now, write_in_place, output_target, &
              trajectory_sibling, clear_mpiio_semaphore

    interface
        integer(c_int) function c_resolve(path, out, outlen) bind(C, name='terrace_resolve_path')
            import :: c_int, c_char
            character(kind=c_char), intent(in) :: path(*)
            character(kind=c_char), intent(out) :: out(*)
            integer(c_int), value :: outlen
        end function c_resolve
        integer(c_int) function c_output_target(path, out, outlen) bind(C, name='terrace_output_target')
            import :: c_int, c_char
            character(kind=c_char), intent(in) :: path(*)
            character(kind=c_char), intent(out) :: out(*)
            integer(c_int), value :: outlen
        end function c_output_target
        integer(c_int) function c_rename(from, to) bind(C, name='terrace_rename')
            import :: c_int, c_char
            character(kind=c_char), intent(in) :: from(*), to(*)
        end function c_rename
        !> 1 kind, 2 writable, 3 unlink, 4 lock, 5 remove at exit, 6 keep at exit, 7 clear the MPI-IO
        !> semaphore of the name (file_ops.c)
        integer(c_int) function c_path_op(op, path) bind(C, name='terrace_path_op')
            import :: c_int, c_char
            integer(c_int), value :: op
            character(kind=c_char), intent(in) :: path(*)
        end function c_path_op
        subroutine cleanup_now() bind(C, name='terrace_cleanup_now')
        end subroutine cleanup_now
        integer(c_int) function c_pid() bind(C, name='terrace_pid')
            import :: c_int
        end function c_pid
    end interface

    !> Runs with checkpoints write their small outputs in place (no temporary name): a killed job
    !> must leave its thermo lines and forces file where the restart continues them.
    logical :: in_place = .false.

contains

    subroutine write_in_place(on)
        logical, intent(in) :: on
        in_place = on
    end subroutine write_in_place

    !> Absolute, symlink-free path (resolved through the directory for a file not yet there).
    !> ok = .false. when the directory does not exist.
    function resolve_path(path, ok) result(abs_path)
        character(len=*), intent(in) :: path
        logical, intent(out) :: ok
        character(len=:), allocatable :: abs_path
        character(kind=c_char, len=8192) :: buf
        integer(c_int) :: rc
        buf = ''
        rc = c_resolve(trim(path)//c_null_char, buf, int(len(buf), c_int))
        ok = rc == 0
        abs_path = c_path_result(rc, buf, path)
    end function resolve_path

    !> The file an output is written to: path itself, or the file a symbolic link path points to
    !> (followed through a chain of links, also when the target does not exist yet), so that an
    !> output renamed into place replaces the link's target and keeps the link.
    function output_target(path) result(target)
        character(len=*), intent(in) :: path
        character(len=:), allocatable :: target
        character(kind=c_char, len=8192) :: buf
        buf = ''
        target = c_path_result(c_output_target(trim(path)//c_null_char, buf, int(len(buf), c_int)), buf, path)
    end function output_target

    !> The path a C helper wrote into buf (up to its NUL) when it succeeded (rc = 0), else path
    !> itself (trimmed).
    function c_path_result(rc, buf, path) result(s)
        integer(c_int), intent(in) :: rc
        character(kind=c_char, len=*), intent(in) :: buf
        character(len=*), intent(in) :: path
        character(len=:), allocatable :: s
        if (rc /= 0) then
            s = trim(path)
        else
            s = buf(1:index(buf, c_null_char) - 1)
        end if
    end function c_path_result

    !> A file that goes with a trajectory: its path with a final .h5, .h5md or .hdf5 replaced by
    !> suffix (cube.h5 -> cube.xdmf), or suffix appended to any other name.
    function trajectory_sibling(trajectory, suffix) result(path)
        character(len=*), intent(in) :: trajectory, suffix
        character(len=:), allocatable :: path
        character(len=:), allocatable :: t
        integer :: k, n, m
        character(len=5), parameter :: ext(3) = ['.h5  ', '.h5md', '.hdf5']
        t = trim(trajectory)
        n = len(t)
        do k = 1, size(ext)
            m = len_trim(ext(k))
            if (n <= m) cycle
            if (t(n - m + 1:n) == ext(k)(1:m) .and. t(n - m:n - m) /= '/') then
                path = t(1:n - m)//suffix
                return
            end if
        end do
        path = t//suffix
    end function trajectory_sibling

    !> The directory part of a path ('.' for a bare name).
    function directory_of(path) result(dir)
        character(len=*), intent(in) :: path
        character(len=:), allocatable :: dir
        integer :: p
        p = index(trim(path), '/', back=.true.)
        if (p == 0) then
            dir = '.'
        else if (p == 1) then
            dir = '/'
        else
            dir = path(1:p - 1)
        end if
    end function directory_of

    integer function path_kind(path)
        character(len=*), intent(in) :: path
        path_kind = int(c_path_op(1_c_int, trim(path)//c_null_char))
    end function path_kind

    logical function is_writable(path)
        character(len=*), intent(in) :: path
        is_writable = c_path_op(2_c_int, trim(path)//c_null_char) == 1
    end function is_writable

    !> Atomic rename; returns 0 or the errno.
    integer function rename_file(from, to)
        character(len=*), intent(in) :: from, to
        rename_file = int(c_rename(trim(from)//c_null_char, trim(to)//c_null_char))
    end function rename_file

    integer function remove_file(path)
        character(len=*), intent(in) :: path
        remove_file = int(c_path_op(3_c_int, trim(path)//c_null_char))
    end function remove_file

    !> 0: locked (the lock file is removed at exit); 1: held by another process; 2: cannot create.
    integer function lock_file(path)
        character(len=*), intent(in) :: path
        lock_file = int(c_path_op(4_c_int, trim(path)//c_null_char))
    end function lock_file

    !> Remove path at exit (an uncommitted output), unless keep_at_exit is called first. Runs that
    !> write in place keep their outputs, except for files registered with always = .true.
    !> (a checkpoint's temporary file).
    subroutine remove_at_exit(path, always)
        character(len=*), intent(in) :: path
        logical, intent(in), optional :: always
        integer :: rc
        logical :: force
        force = .false.
        if (present(always)) force = always
        if (in_place .and. .not. force) return
        rc = int(c_path_op(5_c_int, trim(path)//c_null_char))
    end subroutine remove_at_exit

    subroutine keep_at_exit(path)
        character(len=*), intent(in) :: path
        integer :: rc
        rc = int(c_path_op(6_c_int, trim(path)//c_null_char))
    end subroutine keep_at_exit

    !> The temporary name an output is written under: '.NAME.terrace-partial' in the directory of
    !> the file it will replace (output_target: a symbolic link's target, so that the rename
    !> stays on one file system and the link stays).
    function temporary_name(path) result(tmp)
        character(len=*), intent(in) :: path
        character(len=:), allocatable :: tmp, target
        integer :: p
        if (in_place) then
            tmp = trim(path)
            return
        end if
        target = output_target(path)
        p = index(target, '/', back=.true.)
        tmp = target(1:p)//'.'//target(p + 1:)//'.terrace-partial'
    end function temporary_name

    !> Rename the complete temporary file over the output (over a symbolic link's target). ok = .false. with msg on failure.
    subroutine commit_output(path, ok, msg)
        character(len=*), intent(in) :: path
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: rc
        character(len=16) :: s
        ok = .true.; msg = ''
        if (in_place) return
        rc = rename_file(temporary_name(path), output_target(path))
        ok = rc == 0
        msg = ''
        if (.not. ok) then
            write (s, '(i0)') rc
            msg = 'cannot rename '//temporary_name(path)//' to '//output_target(path)//' (errno '//trim(s)//')'
        end if
        call keep_at_exit(temporary_name(path))
    end subroutine commit_output

    !> gfortran reports no error when a formatted write, flush or close hits a full disk (the
    !> buffered bytes are dropped silently), so a writer counts the bytes it wrote and compares
    !> them with the size of the closed file: ok = .false. with msg when they differ.
    subroutine check_size(path, expected, ok, msg)
        character(len=*), intent(in) :: path
        integer(kind=8), intent(in) :: expected
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer(kind=8) :: n
        character(len=24) :: a, b
        inquire (file=path, size=n)
        ok = n == expected
        msg = ''
        if (ok) return
        write (a, '(i0)') n
        write (b, '(i0)') expected
        msg = 'the file system kept '//trim(a)//' of the '//trim(b)//' bytes written (is the disk full?)'
    end subroutine check_size

    integer function process_id()
        process_id = int(c_pid())
    end function process_id

    !> Before a collective MPI-IO open of path (on every rank, then a barrier): remove the
    !> semaphore Open MPI's shared-file-pointer component keeps per file name, which a killed job
    !> may have left locked (file_ops.c, terrace_mpiio_clear_semaphore).
    subroutine clear_mpiio_semaphore(path)
        character(len=*), intent(in) :: path
        integer(c_int) :: rc
        rc = c_path_op(7_c_int, trim(path)//c_null_char)
    end subroutine clear_mpiio_semaphore

end module terrace_file_ops
