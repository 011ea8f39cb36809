!> Reader for LAMMPS data files, atom_style atomic: header counts and box bounds, then the
!> sections Masses, Atoms (id type x y z [ix iy iz]) and Velocities (id vx vy vz), matched by id,
!> and Pair Coeffs / PairIJ Coeffs as write_data writes them (kept for the check against
!> &potential). Other Coeffs sections are skipped (they do not apply to atomic systems); molecular
!> topology, a tilted box, or a malformed line is an error naming the file and line.
module terrace_lammps_data
    use terrace_kinds, only: dp, i8
    use terrace_atom_table, only: atom_table_t, open_table_file
    use terrace_text, only: count_tokens
    use terrace_config, only: max_types
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    implicit none
    private

    public :: read_lammps_data

    !> The state of one read: the open file, the line reached and the line read last (a section's
    !> header line while its section is read), and which sections have been seen.
    type :: data_reader_t
        character(len=:), allocatable :: path
        integer :: unit = -1, line = 0
        integer(i8) :: nbytes = 0                    !< the file's size (bounds the atom count)
        character(len=1024) :: buf = ''
        character(len=32) :: section = ''           !< the section being read ('' after the last)
        logical :: seen_masses = .false., seen_atoms = .false., seen_vel = .false., seen_coeffs = .false.
        logical, allocatable :: vel_set(:)           !< (n) the atoms given a velocity
    end type data_reader_t

contains

    subroutine fail(t, path, line, msg)
        type(atom_table_t), intent(inout) :: t
        character(len=*), intent(in) :: path, msg
        integer, intent(in) :: line
        character(len=16) :: ln
        if (.not. t%ok) return
        t%ok = .false.
        write (ln, '(i0)') line
        t%error = path//':'//trim(ln)//': &system: read_data: '//msg
    end subroutine fail

    !> Read the data file on the calling rank (rank 0); errors are returned in t%ok / t%error.
    !> Every count in the header is bounded by what the file's size can hold before anything is
    !> allocated, and every number is finite.
    subroutine read_lammps_data(path, t)
        character(len=*), intent(in) :: path
        type(atom_table_t), intent(out) :: t
        type(data_reader_t) :: r
        integer(i8), allocatable :: order(:)
        logical :: opened
        integer :: ios, k

        call open_table_file(t, path, 'read_data', 'data file', r%unit, opened)
        if (.not. opened) return
        r%path = path
        inquire (unit=r%unit, size=r%nbytes)
        r%line = 1
        read (r%unit, '(a)', iostat=ios) r%buf   ! title line
        if (ios /= 0) then
            call fail(t, path, r%line, 'empty data file')
            close (r%unit); return
        end if
        call read_header(r, t)
        if (.not. t%ok) then
            close (r%unit); return
        end if
        allocate (t%x(3, t%n), t%v(3, t%n), t%type(t%n), t%image(3, t%n), t%id(t%n), t%mass(t%ntypes))
        allocate (t%coeff(2, t%ntypes, t%ntypes), t%coeff_given(t%ntypes, t%ntypes))
        allocate (r%vel_set(t%n))
        t%x = 0; t%v = 0; t%image = 0; t%mass = -1; r%vel_set = .false.
        t%coeff = 0; t%coeff_given = .false.
        call read_sections(r, t)
        close (r%unit)
        if (t%ok .and. .not. r%seen_atoms) call fail(t, path, r%line, 'no Atoms section')
        if (t%ok) then
            call sort_index(t%id, order)
            do k = 2, t%n
                if (t%id(order(k)) == t%id(order(k - 1))) then
                    call fail(t, path, r%line, 'duplicate atom id in Atoms'); exit
                end if
            end do
        end if
    end subroutine read_lammps_data

    !> The header lines after the title, up to the first section name (left in r%section); the
    !> box, the atom count and the number of types must all be there.
    subroutine read_header(r, t)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        character(len=:), allocatable :: s
        logical :: have(3)
        integer :: ios
        have = .false.
        r%section = ''
        do
            read (r%unit, '(a)', iostat=ios) r%buf
            if (ios /= 0) exit
            r%line = r%line + 1
            s = strip(r%buf)
            if (len(s) == 0) cycle
            if (.not. header_line(r, t, s, have)) then
                r%section = section_name(s)
                exit
            end if
            if (.not. t%ok) exit
        end do
        t%has_box = all(have)
        if (t%ok .and. .not. t%has_box) call fail(t, r%path, r%line, 'missing box bounds (xlo xhi, ylo yhi, zlo zhi)')
        if (t%ok .and. t%n == 0) call fail(t, r%path, r%line, 'the data file has no atoms')
        if (t%ok .and. t%ntypes == 0) call fail(t, r%path, r%line, "missing 'N atom types' header line")
    end subroutine read_header

    !> One non-blank header line s: the counts and box bounds it gives go into t (have: which box
    !> bounds were given); .false. when s is no header line (a section name).
    logical function header_line(r, t, s, have) result(is_header)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        character(len=*), intent(in) :: s
        logical, intent(inout) :: have(3)
        integer :: ios, k
        integer(i8) :: nheader
        is_header = .true.
        if (ends_with(s, 'atoms') .and. scan(s(1:1), '0123456789+-') > 0) then
            call atom_count_line(r, t, s)
        else if (ends_with(s, 'atom types')) then
            read (s, *, iostat=ios) nheader
            if (ios /= 0 .or. nheader < 1) call fail(t, r%path, r%line, 'cannot read the number of atom types')
            if (t%ok .and. nheader > max_types) call fail(t, r%path, r%line, trim(s)// &
                ': more atom types than Terrace supports (max '//trim(i8_text(int(max_types, i8)))//')')
            if (t%ok) t%ntypes = int(nheader)
        else if (index(s, 'xlo xhi') > 0 .or. index(s, 'ylo yhi') > 0 .or. index(s, 'zlo zhi') > 0) then
            call box_bounds_line(r, t, s, have)
        else if (index(s, 'xy xz yz') > 0) then
            call fail(t, r%path, r%line, 'triclinic boxes are not supported (orthorhombic only)')
        else if (ends_with(s, 'bonds') .or. ends_with(s, 'angles') .or. ends_with(s, 'dihedrals') .or. &
                 ends_with(s, 'impropers')) then
            read (s, *, iostat=ios) k
            if (ios /= 0 .or. k /= 0) call fail(t, r%path, r%line, "'"//s//"': molecular topology is not "// &
                                                'supported (atom_style atomic only)')
        else if (ends_with(s, 'types') .or. index(s, 'per atom') > 0) then
            ! bond/angle/... types with no bonds (as write_data writes them): nothing to use
            read (s, *, iostat=ios) k
            if (ios /= 0) call fail(t, r%path, r%line, "cannot read the header line '"//s//"'")
        else if (scan(s(1:1), '0123456789+-.') > 0) then
            call fail(t, r%path, r%line, "unknown header line '"//s//"' (allowed: N atoms, N atom types, "// &
                      'xlo xhi, ylo yhi, zlo zhi)')
        else
            is_header = .false.
        end if
    end function header_line

    !> "N atoms": N within what the file's size can hold.
    subroutine atom_count_line(r, t, s)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        character(len=*), intent(in) :: s
        character(len=24) :: cnt
        integer(i8) :: nheader
        integer :: ios
        read (s, *, iostat=ios) nheader
        if (ios /= 0 .or. nheader < 0) call fail(t, r%path, r%line, 'cannot read the atom count')
        ! an Atoms line is at least "1 1 0 0 0" and a line end: 10 bytes
        if (t%ok .and. nheader > r%nbytes/10) then
            write (cnt, '(i0)') r%nbytes
            call fail(t, r%path, r%line, 'the header says '//s//' but the file ('//trim(cnt)// &
                      ' bytes) can hold at most '//trim(i8_text(r%nbytes/10))//' Atoms lines')
        end if
        if (t%ok) t%n = int(nheader)
    end subroutine atom_count_line

    !> "lo hi xlo xhi" (or y, z): finite, lo < hi, within 1e9.
    subroutine box_bounds_line(r, t, s, have)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        character(len=*), intent(in) :: s
        logical, intent(inout) :: have(3)
        real(dp) :: a, b
        integer :: ios, k
        read (s, *, iostat=ios) a, b
        if (ios == 0) then
            if (.not. (ieee_is_finite(a) .and. ieee_is_finite(b))) then
                call fail(t, r%path, r%line, 'box bounds must be finite numbers (found '//s//')')
            else if (.not. (b > a) .or. abs(a) > 1.0e9_dp .or. abs(b) > 1.0e9_dp) then
                call fail(t, r%path, r%line, 'bad box bounds (need lo < hi, |lo|, |hi| <= 1e9; found '//s//')')
            end if
        else
            call fail(t, r%path, r%line, 'cannot read box bounds (need lo < hi)')
        end if
        k = merge(1, merge(2, 3, index(s, 'ylo') > 0), index(s, 'xlo') > 0)
        t%lo(k) = a; t%hi(k) = b; have(k) = .true.
    end subroutine box_bounds_line

    !> The sections, from the one named in r%section to the end of the file or the first failure.
    subroutine read_sections(r, t)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        do while (len_trim(r%section) > 0 .and. t%ok)
            select case (trim(r%section))
            case ('Masses')
                call read_masses(r, t)
            case ('Atoms')
                call read_atoms(r, t)
            case ('Velocities')
                call read_velocities(r, t)
            case ('Pair Coeffs', 'PairIJ Coeffs')
                call read_pair_coeffs(r, t)
            case ('Bonds', 'Angles', 'Dihedrals', 'Impropers')
                call fail(t, r%path, r%line, "section '"//trim(r%section)//"': molecular topology is not "// &
                          'supported (atom_style atomic only)'); exit
            case default
                if (ends_with(trim(r%section), 'Coeffs')) then
                    ! Bond Coeffs, Angle Coeffs, ...: nothing to apply in an atomic system
                    t%notes = trim(t%notes)//" '"//trim(r%section)//"'"
                    call skip_section(r%unit, r%buf, r%line)
                    r%section = section_name(strip(r%buf))
                    cycle
                end if
                call fail(t, r%path, r%line, "section '"//trim(r%section)//"' is not supported (allowed: Masses, "// &
                          'Atoms, Velocities, Pair Coeffs, PairIJ Coeffs; other Coeffs sections are skipped)')
            end select
            if (.not. t%ok) exit
            call next_section(r, t)
        end do
    end subroutine read_sections

    !> After a section's lines: the next section name (blank at the end of the file) into r%section.
    subroutine next_section(r, t)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        character(len=:), allocatable :: s
        integer :: ios
        r%section = ''
        do
            read (r%unit, '(a)', iostat=ios) r%buf
            if (ios /= 0) exit
            r%line = r%line + 1
            s = strip(r%buf)
            if (len(s) > 0) then
                if (scan(s(1:1), '0123456789+-.') > 0) then
                    call fail(t, r%path, r%line, 'a data line where a section name was expected (more lines '// &
                              'than the header counts? the header says '//trim(i8_text(int(t%n, i8)))// &
                              ' atoms, '//trim(i8_text(int(t%ntypes, i8)))//' atom types)')
                    exit
                end if
                r%section = section_name(s)
                exit
            end if
        end do
    end subroutine next_section

    subroutine read_masses(r, t)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        real(dp) :: a
        integer :: ios, k, i
        if (r%seen_masses) then
            call fail(t, r%path, r%line, 'a second Masses section'); return
        end if
        r%seen_masses = .true.
        do k = 1, t%ntypes
            call next_data_line(r%unit, r%buf, r%line, ios)
            if (ios /= 0) then
                call fail(t, r%path, r%line, 'Masses section ends early'); exit
            end if
            read (r%buf, *, iostat=ios) i, a
            if (ios /= 0) then
                call fail(t, r%path, r%line, 'bad Masses line (expected: type mass)'); exit
            end if
            if (i < 1 .or. i > t%ntypes) then
                call fail(t, r%path, r%line, 'Masses line for type '//trim(i8_text(int(i, i8)))// &
                          ', but the header says '//trim(i8_text(int(t%ntypes, i8)))//' atom types'); exit
            end if
            if (.not. (a > 0 .and. a <= 1.0e9_dp)) then
                call fail(t, r%path, r%line, 'bad mass (must be a finite number in (0, 1e9]): '//trim(r%buf)); exit
            end if
            t%mass(i) = a
        end do
        t%has_masses = all(t%mass > 0)
    end subroutine read_masses

    subroutine read_atoms(r, t)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        character(len=:), allocatable :: s
        real(dp) :: vals(8)
        integer(i8) :: id
        integer :: ios, k, i, ntok
        if (r%seen_atoms) then
            call fail(t, r%path, r%line, 'a second Atoms section (a data file has one)'); return
        end if
        r%seen_atoms = .true.
        if (index(r%buf, '#') > 0) then
            s = strip(r%buf(index(r%buf, '#') + 1:))
            if (s /= 'atomic') call fail(t, r%path, r%line, "Atoms section style '"//s// &
                                         "' is not supported (atomic only)")
        end if
        do k = 1, t%n
            call next_data_line(r%unit, r%buf, r%line, ios)
            if (ios /= 0) then
                call fail(t, r%path, r%line, 'Atoms section ends early (fewer lines than the atom count)'); exit
            end if
            ntok = count_tokens(r%buf)
            if (ntok /= 5 .and. ntok /= 8) then
                call fail(t, r%path, r%line, 'bad Atoms line (expected: id type x y z [ix iy iz])'); exit
            end if
            vals = 0
            read (r%buf, *, iostat=ios) id, i, vals(1:ntok - 2)
            if (ios /= 0 .or. id < 1 .or. i < 1 .or. i > t%ntypes) then
                call fail(t, r%path, r%line, 'bad Atoms line (expected: id type x y z [ix iy iz], '// &
                          '1 <= type <= atom types)'); exit
            end if
            if (.not. all(ieee_is_finite(vals(1:3)))) then
                call fail(t, r%path, r%line, 'bad Atoms line: the coordinates must be finite numbers'); exit
            end if
            if (any(abs(vals(4:6)) > 1.0e9_dp) .or. any(vals(4:6) /= aint(vals(4:6)))) then
                call fail(t, r%path, r%line, 'bad Atoms line: image flags must be integers of magnitude '// &
                          'at most 1e9'); exit
            end if
            t%id(k) = id; t%type(k) = i; t%x(:, k) = vals(1:3)
            t%image(:, k) = nint(vals(4:6))
        end do
    end subroutine read_atoms

    !> Velocities matched to the atoms by id, each atom at most once.
    subroutine read_velocities(r, t)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        integer(i8), allocatable :: order(:)
        real(dp) :: vals(3)
        integer(i8) :: id
        integer :: ios, k, p
        if (.not. r%seen_atoms) then
            call fail(t, r%path, r%line, 'Velocities section before the Atoms section'); return
        end if
        if (r%seen_vel) then
            call fail(t, r%path, r%line, 'a second Velocities section'); return
        end if
        r%seen_vel = .true.
        call sort_index(t%id, order)
        do k = 1, t%n
            call next_data_line(r%unit, r%buf, r%line, ios)
            if (ios /= 0) then
                call fail(t, r%path, r%line, 'Velocities section ends early'); exit
            end if
            read (r%buf, *, iostat=ios) id, vals(1:3)
            if (ios /= 0 .or. count_tokens(r%buf) /= 4) then
                call fail(t, r%path, r%line, 'bad Velocities line (expected: id vx vy vz)'); exit
            end if
            if (.not. all(ieee_is_finite(vals(1:3)))) then
                call fail(t, r%path, r%line, 'bad Velocities line: the velocities must be finite numbers'); exit
            end if
            p = find_id(t%id, order, id)
            if (p == 0) then
                call fail(t, r%path, r%line, 'Velocities line for an atom id that is not in Atoms'); exit
            end if
            if (r%vel_set(p)) then
                call fail(t, r%path, r%line, 'Velocities line for an atom id given before (each atom once)'); exit
            end if
            t%v(:, p) = vals(1:3); r%vel_set(p) = .true.
        end do
        t%has_velocities = all(r%vel_set)
    end subroutine read_velocities

    !> Pair Coeffs (type epsilon sigma) or PairIJ Coeffs (type type epsilon sigma), as write_data
    !> writes them, with the pair style named in the section line's comment.
    subroutine read_pair_coeffs(r, t)
        type(data_reader_t), intent(inout) :: r
        type(atom_table_t), intent(inout) :: t
        real(dp) :: vals(2)
        logical :: diagonal
        integer :: ios, k, i, j
        if (r%seen_coeffs) then
            call fail(t, r%path, r%line, 'a second pair coefficient section'); return
        end if
        r%seen_coeffs = .true.
        diagonal = trim(r%section) == 'Pair Coeffs'
        if (index(r%buf, '#') > 0) t%coeff_style = strip(r%buf(index(r%buf, '#') + 1:))
        do k = 1, merge(t%ntypes, t%ntypes*(t%ntypes + 1)/2, diagonal)
            call next_data_line(r%unit, r%buf, r%line, ios)
            if (ios /= 0) then
                call fail(t, r%path, r%line, trim(r%section)//' section ends early'); exit
            end if
            vals = 0
            if (diagonal) then
                read (r%buf, *, iostat=ios) i, vals(1:2)
                j = i
            else
                read (r%buf, *, iostat=ios) i, j, vals(1:2)
            end if
            if (ios /= 0 .or. i < 1 .or. i > t%ntypes .or. j < 1 .or. j > t%ntypes .or. &
                .not. all(ieee_is_finite(vals(1:2)))) then
                call fail(t, r%path, r%line, 'bad '//trim(r%section)//' line (expected: '// &
                          trim(merge('type epsilon sigma     ', 'type type epsilon sigma', diagonal))// &
                          ', finite numbers)'); exit
            end if
            t%coeff(:, i, j) = vals(1:2); t%coeff(:, j, i) = vals(1:2)
            t%coeff_given(i, j) = .true.; t%coeff_given(j, i) = .true.
        end do
    end subroutine read_pair_coeffs

    !> Skip the lines of a section that does not apply; buf holds the next section's header line
    !> on return (blank at the end of the file).
    subroutine skip_section(unit, buf, line)
        integer, intent(in) :: unit
        character(len=*), intent(inout) :: buf
        integer, intent(inout) :: line
        integer :: ios
        character(len=:), allocatable :: s
        do
            read (unit, '(a)', iostat=ios) buf
            if (ios /= 0) then
                buf = ''; return
            end if
            line = line + 1
            s = strip(buf)
            if (len(s) == 0) cycle
            if (scan(s(1:1), '0123456789+-.') == 0) return
        end do
    end subroutine skip_section

    !> The section keyword of a header line: the words before any '#', single-spaced.
    function section_name(s) result(w)
        character(len=*), intent(in) :: s
        character(len=32) :: w
        character(len=64) :: a, b
        integer :: ios
        a = ''; b = ''
        read (s, *, iostat=ios) a, b
        if (ios /= 0) b = ''
        if (trim(b) == 'Coeffs') then
            w = trim(a)//' Coeffs'
        else
            w = trim(a)
        end if
    end function section_name

    pure logical function ends_with(s, tail)
        character(len=*), intent(in) :: s, tail
        integer :: n
        n = len_trim(s)
        ends_with = .false.
        if (n < len(tail)) return
        ends_with = s(n - len(tail) + 1:n) == tail
        if (ends_with .and. n > len(tail)) ends_with = s(n - len(tail):n - len(tail)) == ' '
    end function ends_with

    pure function i8_text(i) result(s)
        integer(i8), intent(in) :: i
        character(len=24) :: s
        write (s, '(i0)') i
    end function i8_text

    subroutine next_data_line(unit, buf, line, ios)
        integer, intent(in) :: unit
        character(len=*), intent(inout) :: buf
        integer, intent(inout) :: line
        integer, intent(out) :: ios
        do
            read (unit, '(a)', iostat=ios) buf
            if (ios /= 0) return
            line = line + 1
            if (index(buf, '#') > 0) buf(index(buf, '#'):) = ' '
            if (len_trim(buf) > 0) return
        end do
    end subroutine next_data_line

    function strip(buf) result(s)
        character(len=*), intent(in) :: buf
        character(len=:), allocatable :: s
        integer :: p
        p = index(buf, '#')
        if (p > 0) then
            s = trim(adjustl(buf(1:p - 1)))
        else
            s = trim(adjustl(buf))
        end if
    end function strip



    !> order such that id(order) is ascending (merge sort, stable).
    subroutine sort_index(id, order)
        integer(i8), intent(in) :: id(:)
        integer(i8), allocatable, intent(out) :: order(:)
        integer(i8), allocatable :: tmp(:)
        integer :: n, width, i, lo, mid, hi, a, b, k
        n = size(id)
        allocate (order(n), tmp(n))
        order = [(int(i, i8), i=1, n)]
        width = 1
        do while (width < n)
            do lo = 1, n, 2*width
                mid = min(lo + width, n + 1); hi = min(lo + 2*width, n + 1)
                a = lo; b = mid; k = lo
                do while (k < hi)
                    if (a < mid .and. (b >= hi .or. id(order(min(a, n))) <= id(order(min(b, n))))) then
                        tmp(k) = order(a); a = a + 1
                    else
                        tmp(k) = order(b); b = b + 1
                    end if
                    k = k + 1
                end do
            end do
            order = tmp
            width = 2*width
        end do
    end subroutine sort_index

    integer function find_id(id, order, key) result(p)
        integer(i8), intent(in) :: id(:), order(:), key
        integer :: lo, hi, mid
        lo = 1; hi = size(order); p = 0
        do while (lo <= hi)
            mid = (lo + hi)/2
            if (id(order(mid)) == key) then
                p = int(order(mid)); return
            else if (id(order(mid)) < key) then
                lo = mid + 1
            else
                hi = mid - 1
            end if
        end do
    end function find_id

end module terrace_lammps_data
