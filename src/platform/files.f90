!> What the operating system gives the program: the whole contents of a text file (read_input_text:
!> read by rank 0 and broadcast, for the input decks), this process's peak resident memory, and the
!> name of an output file's part (a restart that writes new files).
!>
!> peak_memory_kib reads VmHWM ("high water mark" of the resident set, in KiB) from
!> /proc/self/status; it is 0 where /proc is not available.
module terrace_files
    use terrace_kinds, only: i8
    use terrace_mpi_env, only: world, bcast_text
    use terrace_errors, only: stop_all
    use terrace_file_ops, only: path_kind, path_missing, path_regular, path_directory
    implicit none
    private

    public :: slurp, read_input_text, peak_memory_kib, part_path

contains

    !> The whole file `path` as one string (line ends kept); status /= 0 when it cannot be read.
    subroutine slurp(path, text, status)
        character(len=*), intent(in) :: path
        character(len=:), allocatable, intent(out) :: text
        integer, intent(out) :: status
        integer :: unit, n
        open (newunit=unit, file=path, access='stream', form='unformatted', status='old', &
              action='read', iostat=status)
        if (status /= 0) return
        inquire (unit=unit, size=n)
        allocate (character(len=max(n, 0)) :: text)
        if (n > 0) read (unit, iostat=status) text
        close (unit)
    end subroutine slurp

    !> The input file `path` on every rank: read by rank 0, broadcast (collective). Stops every rank
    !> when it cannot be read, saying why: no such file, a directory, not a regular file (a device
    !> such as /dev/zero, a pipe: never read, it may not end), or unreadable.
    subroutine read_input_text(path, text)
        character(len=*), intent(in) :: path
        character(len=:), allocatable, intent(out) :: text
        character(len=:), allocatable :: status_text
        integer :: status
        status_text = ''
        if (world%rank == 0) then
            select case (path_kind(path))
            case (path_missing)
                status_text = ': cannot open the input file: no such file'
            case (path_directory)
                status_text = ': the input file is a directory (give the deck, a namelist file)'
            case (path_regular)
                call slurp(path, text, status)
                if (status /= 0) status_text = ': cannot read the input file (is it readable?)'
            case default
                status_text = ': the input file is not a regular file (a device, pipe or socket); '// &
                              'give the deck, a namelist file'
            end select
            if (len(status_text) > 0) text = ''
        end if
        call bcast_text(status_text)
        if (len(status_text) > 0) call stop_all(path//status_text)
        call bcast_text(text)
    end subroutine read_input_text

    !> Part n of an output file (n >= 2): '.part<n>' before the extension of the file name
    !> (traj.h5 -> traj.part2.h5; out/thermo -> out/thermo.part2); n <= 1 or an empty path: path.
    pure function part_path(path, n) result(p)
        character(len=*), intent(in) :: path
        integer(i8), intent(in) :: n
        character(len=:), allocatable :: p
        character(len=24) :: tag
        integer :: slash, dot
        if (n <= 1 .or. len_trim(path) == 0) then
            p = trim(path)
            return
        end if
        write (tag, '(a,i0)') '.part', n
        slash = index(trim(path), '/', back=.true.)
        dot = index(trim(path), '.', back=.true.)
        if (dot > slash + 1) then
            p = path(1:dot - 1)//trim(tag)//trim(path(dot:))
        else
            p = trim(path)//trim(tag)
        end if
    end function part_path

    !> VmHWM of this process in KiB (0 when /proc is not available).
    integer(i8) function peak_memory_kib() result(kib)
        integer :: unit, ios
        character(len=256) :: line
        kib = 0
        open (newunit=unit, file='/proc/self/status', action='read', status='old', iostat=ios)
        if (ios /= 0) return
        do
            read (unit, '(a)', iostat=ios) line
            if (ios /= 0) exit
            if (line(1:6) == 'VmHWM:') then
                read (line(7:), *, iostat=ios) kib
                exit
            end if
        end do
        close (unit)
    end function peak_memory_kib

end module terrace_files
