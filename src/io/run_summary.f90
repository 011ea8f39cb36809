!> The run summary: a JSON file written at the end of every run (&output summary_file) with what
!> the run was (deck, version, machine, ranks, units), the figures of the closing run log and how
!> it ended. A small JSON writer: the program and the integrators put values under '/'-separated
!> keys ('timing/loop_time_s'), which become nested objects in the order the keys were first put;
!> putting a key again replaces its value. The module receives values only (never the config).
!>
!> Values are held on every rank; only rank 0's are written (the run log's figures exist there).
!> summary_write writes the whole text to '.NAME.terrace-partial' beside NAME and renames it over
!> NAME, so that a reader never sees a partial file. Reals are written with 17 significant digits
!> (they read back bit for bit); a non-finite real is written as null.
module terrace_run_summary
    use terrace_kinds, only: dp, i8
    use terrace_mpi_env, only: world
    use terrace_files, only: slurp
    use terrace_version, only: terrace_version_string
    use terrace_build_info, only: terrace_git_commit, terrace_git_modified
    use terrace_file_ops, only: rename_file, remove_at_exit, keep_at_exit
    use mpi_f08, only: MPI_Get_processor_name, MPI_MAX_PROCESSOR_NAME
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    implicit none
    private

    public :: summary_put, summary_put_raw, summary_text, summary_write, summary_reset
    public :: summary_start, json_string, crc32_hex

    !> Put a value under a key ('group/name'): a real, an integer, a logical or a string; or a list
    !> of reals or of integer(i8) under the keys group//names(k), in that order
    !> (summary_put('group/', names, values)).
    interface summary_put
        module procedure put_r, put_i8, put_i4, put_l, put_s, put_list
    end interface summary_put

    type :: record_t
        character(len=:), allocatable :: key, value   !< value: JSON text
    end type record_t

    type(record_t), allocatable, save :: records(:)
    integer, save :: nrec = 0

contains

    subroutine summary_reset()
        nrec = 0
        if (allocated(records)) deallocate (records)
    end subroutine summary_reset

    !> Put JSON text (a number, a string with its quotes, null, ...) under key.
    subroutine summary_put_raw(key, value)
        character(len=*), intent(in) :: key, value
        type(record_t), allocatable :: grown(:)
        integer :: k
        do k = 1, nrec
            if (records(k)%key == key) then
                records(k)%value = value
                return
            end if
        end do
        if (.not. allocated(records)) allocate (records(32))
        if (nrec == size(records)) then
            allocate (grown(2*size(records)))
            grown(1:nrec) = records(1:nrec)
            call move_alloc(grown, records)
        end if
        nrec = nrec + 1
        records(nrec)%key = key
        records(nrec)%value = value
    end subroutine summary_put_raw

    subroutine put_r(key, x)
        character(len=*), intent(in) :: key
        real(dp), intent(in) :: x
        character(len=40) :: buf
        if (.not. ieee_is_finite(x)) then
            call summary_put_raw(key, 'null')
            return
        end if
        write (buf, '(es24.16e3)') x
        call summary_put_raw(key, trim(adjustl(buf)))
    end subroutine put_r

    subroutine put_i8(key, n)
        character(len=*), intent(in) :: key
        integer(i8), intent(in) :: n
        character(len=24) :: buf
        write (buf, '(i0)') n
        call summary_put_raw(key, trim(buf))
    end subroutine put_i8

    subroutine put_list(group, names, values)
        character(len=*), intent(in) :: group, names(:)
        class(*), intent(in) :: values(size(names))
        integer :: k
        do k = 1, size(names)
            select type (values)
            type is (real(dp))
                call put_r(group//trim(names(k)), values(k))
            type is (integer(i8))
                call put_i8(group//trim(names(k)), values(k))
            end select
        end do
    end subroutine put_list

    subroutine put_i4(key, n)
        character(len=*), intent(in) :: key
        integer, intent(in) :: n
        call put_i8(key, int(n, i8))
    end subroutine put_i4

    subroutine put_l(key, l)
        character(len=*), intent(in) :: key
        logical, intent(in) :: l
        call summary_put_raw(key, trim(merge('true ', 'false', l)))
    end subroutine put_l

    subroutine put_s(key, s)
        character(len=*), intent(in) :: key, s
        call summary_put_raw(key, json_string(s))
    end subroutine put_s

    !> s as a JSON string literal (quotes, backslashes and control characters escaped).
    function json_string(s) result(j)
        character(len=*), intent(in) :: s
        character(len=:), allocatable :: j
        character(len=6) :: u
        integer :: i, c
        j = '"'
        do i = 1, len(s)
            c = ichar(s(i:i))
            select case (c)
            case (34)
                j = j//'\"'
            case (92)
                j = j//'\\'
            case (10)
                j = j//'\n'
            case (9)
                j = j//'\t'
            case (13)
                j = j//'\r'
            case (0:8, 11:12, 14:31, 127)
                write (u, '(a,z4.4)') '\u', c
                j = j//u
            case default
                j = j//s(i:i)
            end select
        end do
        j = j//'"'
    end function json_string

    !> The whole summary as JSON text (an object, two-space indents, a final newline).
    function summary_text() result(t)
        character(len=:), allocatable :: t
        t = render('', 0)//new_line('a')
    end function summary_text

    !> The object of every key under prefix ('' or 'a/b/').
    recursive function render(prefix, depth) result(s)
        character(len=*), intent(in) :: prefix
        integer, intent(in) :: depth
        character(len=:), allocatable :: s, rest, name
        integer :: i, p
        logical :: first
        s = '{'
        first = .true.
        do i = 1, nrec
            if (.not. under(records(i)%key, prefix)) cycle
            rest = records(i)%key(len(prefix) + 1:)
            p = index(rest, '/')
            if (p > 0) then
                name = rest(1:p - 1)
                if (seen_before(i, prefix//name//'/')) cycle
            else
                name = rest
            end if
            s = s//trim(merge(',', ' ', .not. first))//new_line('a')//repeat('  ', depth + 1)//json_string(name)//': '
            if (p > 0) then
                s = s//render(prefix//name//'/', depth + 1)
            else
                s = s//records(i)%value
            end if
            first = .false.
        end do
        if (first) then
            s = '{}'
        else
            s = s//new_line('a')//repeat('  ', depth)//'}'
        end if
    end function render

    logical function under(key, prefix)
        character(len=*), intent(in) :: key, prefix
        under = .false.
        if (len(key) <= len(prefix)) return
        under = key(1:len(prefix)) == prefix
    end function under

    logical function seen_before(i, prefix)
        integer, intent(in) :: i
        character(len=*), intent(in) :: prefix
        integer :: j
        seen_before = .false.
        do j = 1, i - 1
            if (under(records(j)%key, prefix)) then
                seen_before = .true.
                return
            end if
        end do
    end function seen_before

    !> Rank 0 writes the summary to '.NAME.terrace-partial' and renames it over path; ok and msg
    !> are rank 0's (the caller makes the verdict collective).
    subroutine summary_write(path, ok, msg)
        character(len=*), intent(in) :: path
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=:), allocatable :: tmp
        integer :: unit, ios, p, rc
        character(len=16) :: s
        ok = .true.; msg = ''
        if (world%rank /= 0 .or. len_trim(path) == 0) return
        p = index(trim(path), '/', back=.true.)
        tmp = path(1:p)//'.'//trim(path(p + 1:))//'.terrace-partial'
        call remove_at_exit(tmp, always=.true.)
        open (newunit=unit, file=tmp, status='replace', access='stream', form='unformatted', action='write', &
              iostat=ios, iomsg=msg)
        if (ios == 0) write (unit, iostat=ios, iomsg=msg) summary_text()
        if (ios == 0) then
            close (unit, iostat=ios, iomsg=msg)
        else
            close (unit, status='delete')
        end if
        ok = ios == 0
        if (.not. ok) return
        rc = rename_file(tmp, trim(path))
        call keep_at_exit(tmp)
        ok = rc == 0
        if (.not. ok) then
            write (s, '(i0)') rc
            msg = 'cannot rename '//tmp//' to '//trim(path)//' (errno '//trim(s)//')'
        end if
    end subroutine summary_write

    !> The summary's first records, when the run starts: the format, the program (version, git
    !> commit at configure time), the machine, and the deck: its path as given and the CRC-32 of its
    !> text (as zlib.crc32 and gzip compute it), read by rank 0.
    subroutine summary_start(path)
        character(len=*), intent(in) :: path
        character(len=:), allocatable :: text
        integer :: status
        call summary_put('format', 'terrace run summary')
        call summary_put('format_version', 1)
        call summary_put('terrace/version', terrace_version_string)
        call summary_put('terrace/git_commit', terrace_git_commit)
        call summary_put('terrace/git_modified', terrace_git_modified)
        call summary_machine()
        call summary_put('deck/path', path)
        if (world%rank /= 0) return
        call slurp(path, text, status)
        if (status == 0) then
            call summary_put('deck/bytes', len(text))
            call summary_put('deck/crc32', crc32_hex(text))
        end if
    end subroutine summary_start

    !> The machine: rank 0's host name and CPU model (/proc/cpuinfo), and the rank count.
    subroutine summary_machine()
        character(len=MPI_MAX_PROCESSOR_NAME) :: host
        character(len=1024) :: line
        character(len=:), allocatable :: model
        integer :: n, unit, ios, j
        call MPI_Get_processor_name(host, n)
        call summary_put('machine/hostname', host(1:n))
        model = ''
        open (newunit=unit, file='/proc/cpuinfo', status='old', action='read', iostat=ios)
        if (ios == 0) then
            do
                read (unit, '(a)', iostat=ios) line
                if (ios /= 0) exit
                if (index(line, 'model name') /= 1) cycle
                j = index(line, ':')
                if (j > 0) model = trim(adjustl(line(j + 1:)))
                exit
            end do
            close (unit)
        end if
        call summary_put('machine/cpu_model', model)
        call summary_put('machine/ranks', world%nprocs)
    end subroutine summary_machine

    !> CRC-32 (IEEE 802.3, reflected, as zlib.crc32) of text, as 8 lower-case hex digits.
    function crc32_hex(text) result(h)
        character(len=*), intent(in) :: text
        character(len=8) :: h
        integer(i8), parameter :: poly = int(z'EDB88320', i8), mask = int(z'FFFFFFFF', i8)
        integer(i8) :: crc
        integer :: i, b
        crc = mask
        do i = 1, len(text)
            crc = ieor(crc, int(ichar(text(i:i)), i8))
            do b = 1, 8
                if (iand(crc, 1_i8) /= 0) then
                    crc = ieor(shiftr(crc, 1), poly)
                else
                    crc = shiftr(crc, 1)
                end if
            end do
        end do
        crc = ieor(crc, mask)
        write (h, '(z8.8)') crc
        h = lower_hex(h)
    contains
        function lower_hex(s) result(l)
            character(len=*), intent(in) :: s
            character(len=len(s)) :: l
            integer :: k
            l = s
            do k = 1, len(s)
                if (s(k:k) >= 'A' .and. s(k:k) <= 'F') l(k:k) = achar(iachar(s(k:k)) + 32)
            end do
        end function lower_hex
    end function crc32_hex

end module terrace_run_summary
