!> Reader for small explicit scenes: one atom per line, `type x y z [vx vy vz]`, in the run's
!> units; '#' starts a comment. Ids are the line order (1, 2, ...). In 2-D, z and vz must be 0.
module terrace_atoms_file
    use terrace_kinds, only: dp, i8
    use terrace_atom_table, only: atom_table_t, open_table_file
    use terrace_text, only: count_tokens
    use terrace_grow, only: grow_keep
    use terrace_config, only: max_types
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    implicit none
    private

    public :: read_atoms_file

contains

    subroutine read_atoms_file(path, t)
        character(len=*), intent(in) :: path
        type(atom_table_t), intent(out) :: t
        integer :: unit, ios, line, n, nvel, ntok, i, ty
        character(len=1024) :: buf
        real(dp) :: vals(6)
        real(dp), allocatable :: x(:, :), v(:, :)
        integer, allocatable :: types(:)
        character(len=16) :: ln
        logical :: opened

        call open_table_file(t, path, 'atoms_file', 'atoms file', unit, opened)
        if (.not. opened) return
        allocate (x(3, 64), v(3, 64), types(64))
        n = 0; nvel = 0; line = 0
        do
            read (unit, '(a)', iostat=ios) buf
            if (ios /= 0) exit
            line = line + 1
            if (index(buf, '#') > 0) buf(index(buf, '#'):) = ' '
            if (len_trim(buf) == 0) cycle
            ntok = count_tokens(buf)
            vals = 0
            if (ntok == 4 .or. ntok == 7) read (buf, *, iostat=ios) ty, vals(1:ntok - 1)
            if ((ntok /= 4 .and. ntok /= 7) .or. ios /= 0) ty = 0
            if (ty >= 1 .and. .not. all(ieee_is_finite(vals))) then
                write (ln, '(i0)') line
                t%ok = .false.
                t%error = path//':'//trim(ln)//': &system: atoms_file: positions and velocities must be finite numbers'
                close (unit); return
            end if
            if (ty > max_types) then
                write (ln, '(i0)') line
                t%ok = .false.
                write (t%error, '(a,i0,a,i0,a)') path//':'//trim(ln)//': &system: atoms_file: type ', ty, &
                    ': more atom types than Terrace supports (max ', max_types, ')'
                close (unit); return
            end if
            if (ty < 1) then
                write (ln, '(i0)') line
                t%ok = .false.
                t%error = path//':'//trim(ln)//': &system: atoms_file: bad atom line (expected: type x y z [vx vy vz], type >= 1)'
                close (unit); return
            end if
            if (n == size(types)) then
                call grow_keep(x, n, 2*n); call grow_keep(v, n, 2*n); call grow_keep(types, n, 2*n)
            end if
            n = n + 1
            types(n) = ty; x(:, n) = vals(1:3); v(:, n) = vals(4:6)
            if (ntok == 7) nvel = nvel + 1
        end do
        close (unit)
        t%n = n
        if (n == 0) then
            t%ok = .false.
            t%error = path//': &system: atoms_file: the atoms file has no atoms'
            return
        end if
        t%ntypes = maxval(types(1:n))
        allocate (t%x(3, n), t%v(3, n), t%type(n), t%image(3, n), t%id(n), t%mass(t%ntypes))
        t%x = x(:, 1:n); t%v = v(:, 1:n); t%type = types(1:n); t%image = 0
        t%id = [(int(i, i8), i=1, n)]
        t%mass = -1
        t%has_velocities = nvel == n
        if (nvel /= 0 .and. nvel /= n) then
            t%ok = .false.
            t%error = path//': &system: atoms_file: either every atom line gives velocities or none does'
        end if
    end subroutine read_atoms_file

end module terrace_atoms_file
