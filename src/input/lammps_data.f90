!> Reader for LAMMPS data files, atom_style atomic: header counts and box bounds, then the
!> sections Masses, Atoms (id type x y z [ix iy iz]) and Velocities (id vx vy vz), matched by id.
!> Any other section, a tilted box, or a malformed line is an error naming the file and line.
module terrace_lammps_data
    use terrace_kinds, only: dp, i8
    use terrace_atom_table, only: atom_table_t
    use terrace_text, only: count_tokens
    implicit none
    private

    public :: read_lammps_data

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
    subroutine read_lammps_data(path, t)
        character(len=*), intent(in) :: path
        type(atom_table_t), intent(out) :: t
        integer :: unit, ios, line, k, p, natoms_seen, nvel_seen, ntok, i
        character(len=1024) :: buf
        character(len=:), allocatable :: s
        real(dp) :: a, b, vals(8)
        integer(i8) :: id
        integer(i8), allocatable :: order(:)
        logical :: have(3)
        logical, allocatable :: vel_set(:)
        character(len=16) :: section

        open (newunit=unit, file=path, status='old', action='read', iostat=ios)
        if (ios /= 0) then
            t%ok = .false.
            t%error = path//': &system: read_data: cannot open the data file'
            return
        end if
        have = .false.
        line = 1
        read (unit, '(a)', iostat=ios) buf   ! title line
        if (ios /= 0) then
            call fail(t, path, line, 'empty data file')
            close (unit); return
        end if
        section = ''
        ! header
        do
            read (unit, '(a)', iostat=ios) buf
            if (ios /= 0) exit
            line = line + 1
            s = strip(buf)
            if (len(s) == 0) cycle
            if (index(s, 'atoms') > 0 .and. index(s, 'atom types') == 0 .and. scan(s(1:1), '0123456789') > 0) then
                read (s, *, iostat=ios) t%n
                if (ios /= 0 .or. t%n < 0) call fail(t, path, line, 'cannot read the atom count')
            else if (index(s, 'atom types') > 0) then
                read (s, *, iostat=ios) t%ntypes
                if (ios /= 0 .or. t%ntypes < 1) call fail(t, path, line, 'cannot read the number of atom types')
            else if (index(s, 'xlo xhi') > 0 .or. index(s, 'ylo yhi') > 0 .or. index(s, 'zlo zhi') > 0) then
                read (s, *, iostat=ios) a, b
                if (ios /= 0 .or. b <= a) call fail(t, path, line, 'cannot read box bounds (need lo < hi)')
                k = merge(1, merge(2, 3, index(s, 'ylo') > 0), index(s, 'xlo') > 0)
                t%lo(k) = a; t%hi(k) = b; have(k) = .true.
            else if (index(s, 'xy xz yz') > 0) then
                call fail(t, path, line, 'triclinic boxes are not supported (orthorhombic only)')
            else if (index(s, 'bonds') > 0 .or. index(s, 'angles') > 0 .or. index(s, 'dihedrals') > 0 .or. &
                     index(s, 'impropers') > 0 .or. index(s, 'types') > 0) then
                read (s, *, iostat=ios) k
                if (ios == 0 .and. k > 0) call fail(t, path, line, 'molecular topology is not supported (atom_style atomic)')
            else
                section = first_word(s)
                exit
            end if
            if (.not. t%ok) exit
        end do
        t%has_box = all(have)
        if (t%ok .and. .not. t%has_box) call fail(t, path, line, 'missing box bounds (xlo xhi, ylo yhi, zlo zhi)')
        if (t%ok .and. t%n == 0) call fail(t, path, line, 'the data file has no atoms')
        if (t%ok .and. t%ntypes == 0) call fail(t, path, line, "missing 'N atom types' header line")
        if (.not. t%ok) then
            close (unit); return
        end if
        allocate (t%x(3, t%n), t%v(3, t%n), t%type(t%n), t%image(3, t%n), t%id(t%n), t%mass(t%ntypes))
        allocate (vel_set(t%n))
        t%x = 0; t%v = 0; t%image = 0; t%mass = -1; vel_set = .false.
        natoms_seen = 0; nvel_seen = 0
        ! sections
        do while (len_trim(section) > 0 .and. t%ok)
            select case (trim(section))
            case ('Masses')
                do k = 1, t%ntypes
                    call next_data_line(unit, buf, line, ios)
                    if (ios /= 0) then
                        call fail(t, path, line, 'Masses section ends early'); exit
                    end if
                    read (buf, *, iostat=ios) i, a
                    if (ios /= 0 .or. i < 1 .or. i > t%ntypes .or. .not. (a > 0)) then
                        call fail(t, path, line, 'bad Masses line (expected: type mass, mass > 0)'); exit
                    end if
                    t%mass(i) = a
                end do
                t%has_masses = all(t%mass > 0)
            case ('Atoms')
                if (index(buf, '#') > 0) then
                    s = strip(buf(index(buf, '#') + 1:))
                    if (s /= 'atomic') call fail(t, path, line, "Atoms section style '"//s// &
                                                 "' is not supported (atomic only)")
                end if
                do k = 1, t%n
                    call next_data_line(unit, buf, line, ios)
                    if (ios /= 0) then
                        call fail(t, path, line, 'Atoms section ends early (fewer lines than the atom count)'); exit
                    end if
                    ntok = count_tokens(buf)
                    if (ntok /= 5 .and. ntok /= 8) then
                        call fail(t, path, line, 'bad Atoms line (expected: id type x y z [ix iy iz])'); exit
                    end if
                    vals = 0
                    read (buf, *, iostat=ios) id, i, vals(1:ntok - 2)
                    if (ios /= 0 .or. id < 1 .or. i < 1 .or. i > t%ntypes .or. any(vals /= vals)) then
                        call fail(t, path, line, 'bad Atoms line (expected: id type x y z [ix iy iz], '// &
                                  '1 <= type <= atom types)'); exit
                    end if
                    t%id(k) = id; t%type(k) = i; t%x(:, k) = vals(1:3)
                    t%image(:, k) = nint(vals(4:6))
                end do
                natoms_seen = t%n
            case ('Velocities')
                if (natoms_seen == 0) then
                    call fail(t, path, line, 'Velocities section before the Atoms section'); exit
                end if
                call sort_index(t%id, order)
                do k = 1, t%n
                    call next_data_line(unit, buf, line, ios)
                    if (ios /= 0) then
                        call fail(t, path, line, 'Velocities section ends early'); exit
                    end if
                    read (buf, *, iostat=ios) id, vals(1:3)
                    if (ios /= 0) then
                        call fail(t, path, line, 'bad Velocities line (expected: id vx vy vz)'); exit
                    end if
                    p = find_id(t%id, order, id)
                    if (p == 0) then
                        call fail(t, path, line, 'Velocities line for an atom id that is not in Atoms'); exit
                    end if
                    t%v(:, p) = vals(1:3); vel_set(p) = .true.
                end do
                nvel_seen = t%n
                t%has_velocities = all(vel_set)
            case default
                call fail(t, path, line, "section '"//trim(section)//"' is not supported (allowed: Masses, Atoms, "// &
                          "Velocities)")
            end select
            if (.not. t%ok) exit
            section = ''
            do
                read (unit, '(a)', iostat=ios) buf
                if (ios /= 0) exit
                line = line + 1
                s = strip(buf)
                if (len(s) > 0) then
                    section = first_word(s)
                    exit
                end if
            end do
        end do
        close (unit)
        if (t%ok .and. natoms_seen == 0) call fail(t, path, line, 'no Atoms section')
        if (t%ok) then
            call sort_index(t%id, order)
            do k = 2, t%n
                if (t%id(order(k)) == t%id(order(k - 1))) then
                    call fail(t, path, line, 'duplicate atom id in Atoms'); exit
                end if
            end do
        end if
    end subroutine read_lammps_data

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

    function first_word(s) result(w)
        character(len=*), intent(in) :: s
        character(len=16) :: w
        integer :: p
        p = index(s, ' ')
        if (p == 0) then
            w = s
        else
            w = s(1:p - 1)
        end if
    end function first_word


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
