!> Readers of tabulated EAM potential files (the DYNAMO formats that LAMMPS reads), each table
!> kept on the file's own grid; terrace_eam turns them into interpolation tables.
!>
!> funcfl (pair_style eam), one element per file:
!>   line 1     comment
!>   line 2     atomic-number mass [lattice-constant lattice-type]
!>   line 3     nrho drho nr dr cutoff
!>   then       F(rho) at rho = 0, drho, .., (nrho-1) drho         (nrho values, eV)
!>              Z(r)   at r = 0, dr, .., (nr-1) dr                  (nr values, effective charge)
!>              rho(r) at the same r                                (nr values)
!> setfl (pair_style eam/alloy) and its Finnis-Sinclair variant (eam/fs), N elements per file:
!>   lines 1-3  comments
!>   line 4     N element-1 .. element-N
!>   line 5     nrho drho nr dr cutoff
!>   per element: a line 'atomic-number mass [lattice-constant lattice-type]', F(rho) (nrho values),
!>              then rho(r) (nr values; eam/fs: N density functions of nr values, one per element
!>              in file order)
!>   then       r phi(r) for the pairs (i, j), i = 1..N, j = 1..i   (nr values each, eV Angstrom)
!> Values are free-format, several to a line, and a table may run over many lines; each table
!> starts on a new line (the line that ends a table holds nothing else). '#' starts a comment in
!> the table lines; blank lines are skipped. Anything malformed (missing or extra values, a count
!> that disagrees with the header, a token that is not a finite number) is an error naming the
!> file and the line: 'Cu_u3.eam:4: expected 500 values of F(rho), found 312'.
module terrace_eam_files
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use terrace_kinds, only: dp, i8
    use terrace_text, only: int_text
    implicit none
    private

    integer, parameter, public :: eam_name_len = 16

    !> One tabulated EAM file as written.
    type, public :: eam_file_t
        character(len=:), allocatable :: path
        integer :: nelements = 0
        logical :: fs = .false.                          !< Finnis-Sinclair: a density function per element pair
        character(len=eam_name_len), allocatable :: elements(:)   !< setfl/fs names (funcfl: '')
        integer, allocatable :: number(:)                !< atomic numbers
        real(dp), allocatable :: mass(:)                 !< amu
        integer :: nrho = 0, nr = 0
        real(dp) :: drho = 0, dr = 0, cut = 0
        real(dp), allocatable :: frho(:, :)              !< F(rho) (nrho, element)
        !> density functions (nr, k, element): funcfl and setfl k = 1; eam/fs the k-th function listed
        !> in the section of the element
        real(dp), allocatable :: rhor(:, :, :)
        real(dp), allocatable :: zr(:)                   !< funcfl: Z(r) (nr)
        real(dp), allocatable :: z2r(:, :, :)            !< setfl/fs: r phi(r) (nr, i, j), both halves filled
    end type eam_file_t

    public :: read_funcfl_file, read_setfl_file

    !> The text of a file split into lines, with a cursor (the number of the last line consumed).
    type :: text_t
        character(len=:), allocatable :: path, buf
        integer, allocatable :: lo(:), hi(:)             !< line k is buf(lo(k):hi(k))
        integer :: nlines = 0, line = 0
    end type text_t

    character(len=*), parameter :: blanks = ' '//achar(9)//achar(13)//achar(11)//achar(12)

contains

    ! ------------------------------------------------------------------------------------- readers

    !> Read a funcfl file (one element).
    subroutine read_funcfl_file(path, file, ok, msg)
        character(len=*), intent(in) :: path
        type(eam_file_t), intent(out) :: file
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(text_t) :: txt
        character(len=64) :: tok(5)
        integer :: ntok, ln
        call load_text(path, txt, ok, msg)
        if (.not. ok) return
        file%path = path
        file%nelements = 1
        file%fs = .false.
        allocate (file%elements(1), file%number(1), file%mass(1))
        file%elements = ''
        txt%line = 1                                      ! line 1: comment
        call header_line(txt, 'the line "atomic-number mass lattice-constant lattice-type"', tok, ntok, ok, msg)
        if (.not. ok) return
        ln = txt%line
        if (ntok < 2) then
            ok = .false.; msg = where(txt, ln)//'expected "atomic-number mass lattice-constant lattice-type"'
            return
        end if
        call to_int(txt, ln, tok(1), 'the atomic number', file%number(1), ok, msg)
        if (ok) call to_real(txt, ln, tok(2), 'the mass', file%mass(1), ok, msg)
        if (ok) call positive(txt, ln, file%mass(1), 'the mass', ok, msg)
        if (.not. ok) return
        call grid_line(txt, file, ok, msg)
        if (ok) call fits_in_file(txt, int(file%nrho, i8) + 2_i8*file%nr, ok, msg)
        if (.not. ok) return
        allocate (file%frho(file%nrho, 1), file%zr(file%nr), file%rhor(file%nr, 1, 1))
        call read_values(txt, 'F(rho)', file%frho(:, 1), ok, msg)
        if (ok) call read_values(txt, 'Z(r)', file%zr, ok, msg)
        if (ok) call read_values(txt, 'rho(r)', file%rhor(:, 1, 1), ok, msg)
        if (ok) call nothing_after(txt, ok, msg)
    end subroutine read_funcfl_file

    !> Read a setfl file (eam/alloy; fs = .true.: eam/fs).
    subroutine read_setfl_file(path, fs, file, ok, msg)
        character(len=*), intent(in) :: path
        logical, intent(in) :: fs
        type(eam_file_t), intent(out) :: file
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        type(text_t) :: txt
        character(len=64), allocatable :: tok(:)
        character(len=64) :: t5(5)
        character(len=16) :: s
        integer :: ntok, ln, n, i, j, k
        call load_text(path, txt, ok, msg)
        if (.not. ok) return
        file%path = path
        file%fs = fs
        txt%line = 3                                      ! lines 1-3: comments
        ! line 4: N and the N element names
        allocate (tok(1))
        call header_line(txt, 'the line "N element-1 .. element-N"', tok, ntok, ok, msg)
        if (.not. ok) return
        ln = txt%line
        call to_int(txt, ln, tok(1), 'the number of elements', n, ok, msg)
        if (.not. ok) return
        if (n < 1) then
            ok = .false.; msg = where(txt, ln)//'the number of elements must be at least 1, found '//trim(tok(1))
            return
        end if
        call fits_in_file(txt, int(n, i8), ok, msg)
        if (.not. ok) return
        deallocate (tok)
        allocate (tok(n + 2))
        txt%line = ln - 1
        call header_line(txt, '', tok, ntok, ok, msg)
        if (ntok /= n + 1) then
            write (s, '(i0)') n
            ok = .false.
            msg = where(txt, ln)//trim(s)//' elements declared, '//int_text(ntok - 1)//' names given'
            return
        end if
        file%nelements = n
        allocate (file%elements(n), file%number(n), file%mass(n))
        do i = 1, n
            if (len_trim(tok(i + 1)) > eam_name_len) then
                ok = .false.; msg = where(txt, ln)//'element name "'//trim(tok(i + 1))//'" is too long'
                return
            end if
            file%elements(i) = tok(i + 1)(1:eam_name_len)
        end do
        call grid_line(txt, file, ok, msg)
        if (.not. ok) return
        k = 1
        if (fs) k = n
        call fits_in_file(txt, int(n, i8)*file%nrho + int(n, i8)*k*file%nr + int(n, i8)*(n + 1)/2*file%nr, ok, msg)
        if (.not. ok) return
        allocate (file%frho(file%nrho, n), file%rhor(file%nr, k, n), file%z2r(file%nr, n, n))
        do i = 1, n
            call header_line(txt, 'the line "atomic-number mass lattice-constant lattice-type" of element '// &
                             trim(file%elements(i)), t5, ntok, ok, msg)
            if (.not. ok) return
            ln = txt%line
            if (ntok < 2) then
                ok = .false.
                msg = where(txt, ln)//'expected "atomic-number mass lattice-constant lattice-type" of element '// &
                      trim(file%elements(i))
                return
            end if
            call to_int(txt, ln, t5(1), 'the atomic number of '//trim(file%elements(i)), file%number(i), ok, msg)
            if (ok) call to_real(txt, ln, t5(2), 'the mass of '//trim(file%elements(i)), file%mass(i), ok, msg)
            if (ok) call positive(txt, ln, file%mass(i), 'the mass of '//trim(file%elements(i)), ok, msg)
            if (ok) call read_values(txt, 'F(rho) of '//trim(file%elements(i)), file%frho(:, i), ok, msg)
            if (.not. ok) return
            if (fs) then
                do j = 1, n
                    call read_values(txt, 'rho(r) of '//trim(file%elements(i))//' ('//trim(file%elements(j))//')', &
                                     file%rhor(:, j, i), ok, msg)
                    if (.not. ok) return
                end do
            else
                call read_values(txt, 'rho(r) of '//trim(file%elements(i)), file%rhor(:, 1, i), ok, msg)
                if (.not. ok) return
            end if
        end do
        do i = 1, n
            do j = 1, i
                call read_values(txt, 'r*phi(r) of '//trim(file%elements(i))//'-'//trim(file%elements(j)), &
                                 file%z2r(:, i, j), ok, msg)
                if (.not. ok) return
                file%z2r(:, j, i) = file%z2r(:, i, j)
            end do
        end do
        call nothing_after(txt, ok, msg)
    end subroutine read_setfl_file

    !> The line "nrho drho nr dr cutoff".
    subroutine grid_line(txt, file, ok, msg)
        type(text_t), intent(inout) :: txt
        type(eam_file_t), intent(inout) :: file
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=64) :: tok(5)
        integer :: ntok, ln
        call header_line(txt, 'the line "nrho drho nr dr cutoff"', tok, ntok, ok, msg)
        if (.not. ok) return
        ln = txt%line
        if (ntok < 5) then
            ok = .false.; msg = where(txt, ln)//'expected "nrho drho nr dr cutoff", found '//int_text(ntok)//' values'
            return
        end if
        call to_int(txt, ln, tok(1), 'nrho', file%nrho, ok, msg)
        if (ok) call to_real(txt, ln, tok(2), 'drho', file%drho, ok, msg)
        if (ok) call to_int(txt, ln, tok(3), 'nr', file%nr, ok, msg)
        if (ok) call to_real(txt, ln, tok(4), 'dr', file%dr, ok, msg)
        if (ok) call to_real(txt, ln, tok(5), 'the cutoff', file%cut, ok, msg)
        if (ok) call positive(txt, ln, file%drho, 'drho', ok, msg)
        if (ok) call positive(txt, ln, file%dr, 'dr', ok, msg)
        if (ok) call positive(txt, ln, file%cut, 'the cutoff', ok, msg)
        if (.not. ok) return
        if (file%nrho < 5 .or. file%nr < 5) then
            ok = .false.
            msg = where(txt, ln)//'nrho and nr must be at least 5, found '//int_text(file%nrho)//' and '//int_text(file%nr)
        end if
    end subroutine grid_line

    ! ---------------------------------------------------------------------------------- text layer

    !> Read the whole file and split it into lines (LF or CR LF).
    subroutine load_text(path, txt, ok, msg)
        character(len=*), intent(in) :: path
        type(text_t), intent(out) :: txt
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: u, ios, nbytes, i, n, start
        ok = .false.
        txt%path = path
        open (newunit=u, file=path, access='stream', form='unformatted', status='old', action='read', iostat=ios)
        if (ios /= 0) then
            msg = path//': cannot open the file'
            return
        end if
        inquire (unit=u, size=nbytes)
        allocate (character(len=max(nbytes, 0)) :: txt%buf)
        ios = 0
        if (nbytes > 0) read (u, iostat=ios) txt%buf
        close (u)
        if (ios /= 0 .or. nbytes < 0) then
            msg = path//': cannot read the file'
            return
        end if
        n = 1
        do i = 1, nbytes
            if (txt%buf(i:i) == achar(10)) n = n + 1
        end do
        allocate (txt%lo(n), txt%hi(n))
        n = 0; start = 1
        do i = 1, nbytes
            if (txt%buf(i:i) == achar(10)) then
                n = n + 1; txt%lo(n) = start; txt%hi(n) = i - 1; start = i + 1
            end if
        end do
        if (start <= nbytes) then
            n = n + 1; txt%lo(n) = start; txt%hi(n) = nbytes
        end if
        txt%nlines = n
        txt%line = 0
        ok = .true.
        msg = ''
    end subroutine load_text

    !> Refuse a header whose counts ask for more values than the file can hold (each value takes
    !> at least two bytes, a digit and a separator), before anything of that size is allocated.
    subroutine fits_in_file(txt, nvalues, ok, msg)
        type(text_t), intent(in) :: txt
        integer(i8), intent(in) :: nvalues
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=24) :: a, b
        ! up to a million values (8 MB) are allocated and read, so that a file cut short gets the
        ! table reader's precise message ('expected 40 values of F(rho), found 10')
        ok = nvalues <= max(int(len(txt%buf), i8)/2, 1000000_i8)
        msg = ''
        if (ok) return
        write (a, '(i0)') nvalues
        write (b, '(i0)') len(txt%buf)
        msg = where(txt, txt%line)//'the header asks for '//trim(a)//' values, more than the file ('//trim(b)// &
              ' bytes) can hold (are nrho, nr and the number of elements right?)'
    end subroutine fits_in_file

    !> 'path:line: '
    function where(txt, line) result(s)
        type(text_t), intent(in) :: txt
        integer, intent(in) :: line
        character(len=:), allocatable :: s
        s = txt%path//':'//int_text(line)//': '
    end function where


    !> Next token of line k at or after position pos (buffer index); tlo > thi when there is none.
    !> A '#' ends the line.
    pure subroutine next_token(txt, k, pos, tlo, thi)
        type(text_t), intent(in) :: txt
        integer, intent(in) :: k
        integer, intent(inout) :: pos
        integer, intent(out) :: tlo, thi
        integer :: e
        e = txt%hi(k)
        do while (pos <= e)
            if (index(blanks, txt%buf(pos:pos)) == 0) exit
            pos = pos + 1
        end do
        tlo = pos; thi = pos - 1
        if (pos > e) return
        if (txt%buf(pos:pos) == '#') then
            pos = e + 1
            return
        end if
        do while (pos <= e)
            if (index(blanks, txt%buf(pos:pos)) /= 0 .or. txt%buf(pos:pos) == '#') exit
            pos = pos + 1
        end do
        thi = pos - 1
    end subroutine next_token

    !> Advance the cursor to the next line holding a token; .false. at the end of the file.
    logical function next_data_line(txt) result(found)
        type(text_t), intent(inout) :: txt
        integer :: pos, tlo, thi
        found = .false.
        do while (txt%line < txt%nlines)
            txt%line = txt%line + 1
            pos = txt%lo(txt%line)
            call next_token(txt, txt%line, pos, tlo, thi)
            if (thi >= tlo) then
                found = .true.
                return
            end if
        end do
    end function next_data_line

    !> Tokens of the next non-blank line (ntok counts them all; the first size(tok) are stored).
    subroutine header_line(txt, what, tok, ntok, ok, msg)
        type(text_t), intent(inout) :: txt
        character(len=*), intent(in) :: what
        character(len=*), intent(out) :: tok(:)
        integer, intent(out) :: ntok
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: pos, tlo, thi
        ntok = 0
        tok = ''
        ok = next_data_line(txt)
        if (.not. ok) then
            msg = where(txt, max(txt%nlines, 1))//'unexpected end of file, expected '//what
            return
        end if
        pos = txt%lo(txt%line)
        do
            call next_token(txt, txt%line, pos, tlo, thi)
            if (thi < tlo) exit
            ntok = ntok + 1
            if (ntok <= size(tok)) tok(ntok) = txt%buf(tlo:thi)
        end do
        msg = ''
    end subroutine header_line

    !> The next size(y) values, from the next non-blank line on.
    subroutine read_values(txt, what, y, ok, msg)
        type(text_t), intent(inout) :: txt
        character(len=*), intent(in) :: what
        real(dp), intent(out) :: y(:)
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: n, count, start, pos, tlo, thi, ios
        n = size(y)
        count = 0
        start = 0
        ok = .false.
        do while (count < n)
            if (.not. next_data_line(txt)) then
                if (start == 0) then
                    msg = where(txt, max(txt%nlines, 1))//'expected '//int_text(n)//' values of '//what// &
                          ', found the end of the file'
                else
                    msg = where(txt, start)//'expected '//int_text(n)//' values of '//what//', found '//int_text(count)
                end if
                return
            end if
            if (start == 0) start = txt%line
            pos = txt%lo(txt%line)
            do
                call next_token(txt, txt%line, pos, tlo, thi)
                if (thi < tlo) exit
                if (count == n) then
                    msg = where(txt, txt%line)//'more values than the '//int_text(n)//' of '//what// &
                          ' (table starting on line '//int_text(start)//'; each table starts on a new line)'
                    return
                end if
                if (verify(txt%buf(tlo:thi), '0123456789+-.eEdD') /= 0) then
                    msg = where(txt, txt%line)//'"'//txt%buf(tlo:thi)//'" is not a number (value '// &
                          int_text(count + 1)//' of '//int_text(n)//' of '//what//')'
                    return
                end if
                if (.not. in_range(txt%buf(tlo:thi))) then
                    msg = where(txt, txt%line)//'"'//txt%buf(tlo:thi)//'" is out of range (value '// &
                          int_text(count + 1)//' of '//int_text(n)//' of '//what//')'
                    return
                end if
                read (txt%buf(tlo:thi), *, iostat=ios) y(count + 1)
                if (ios /= 0) then
                    msg = where(txt, txt%line)//'"'//txt%buf(tlo:thi)//'" is not a number (value '// &
                          int_text(count + 1)//' of '//int_text(n)//' of '//what//')'
                    return
                end if
                if (.not. ieee_is_finite(y(count + 1))) then
                    msg = where(txt, txt%line)//'"'//txt%buf(tlo:thi)//'" is not a finite number (value '// &
                          int_text(count + 1)//' of '//int_text(n)//' of '//what//')'
                    return
                end if
                count = count + 1
            end do
        end do
        ok = .true.
        msg = ''
    end subroutine read_values

    !> Error when data follow the last table (a count in the header that is too small).
    subroutine nothing_after(txt, ok, msg)
        type(text_t), intent(inout) :: txt
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        ok = .not. next_data_line(txt)
        msg = ''
        if (.not. ok) msg = where(txt, txt%line)//'unexpected data after the last table (do the counts in the '// &
                            'header match the tables?)'
    end subroutine nothing_after

    !> Whether a token of digits, sign, point and exponent is below 1e308 in magnitude (checked on
    !> the text, so that an overflowing value is an error message, not a floating-point trap).
    pure logical function in_range(tok) result(ok)
        character(len=*), intent(in) :: tok
        integer :: e, p, k, expo, first, nint, ios
        ok = .true.
        e = scan(tok, 'eEdD')
        expo = 0
        if (e > 0) then
            k = verify(tok(e + 1:), '+-0')           ! first significant digit of the exponent
            if (k > 0 .and. len(tok) - e - k + 1 > 5) then
                ok = tok(e + 1:e + 1) == '-'         ! a huge negative exponent only underflows
                return
            end if
            read (tok(e + 1:), *, iostat=ios) expo
            if (ios /= 0) return                     ! malformed: the read of the value reports it
        else
            e = len(tok) + 1
        end if
        p = index(tok(1:e - 1), '.')
        if (p == 0) p = e
        ! digits before the point, leading zeros and sign skipped
        first = verify(tok(1:p - 1), '+-0')
        nint = 0
        if (first > 0) nint = p - first
        k = expo + nint - 1                          ! decimal order of magnitude
        ok = k < 308
    end function in_range

    subroutine to_int(txt, line, tok, what, v, ok, msg)
        type(text_t), intent(in) :: txt
        integer, intent(in) :: line
        character(len=*), intent(in) :: tok, what
        integer, intent(out) :: v
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: ios
        v = 0
        ok = len_trim(tok) > 0 .and. verify(trim(tok), '0123456789+-') == 0
        if (ok) then
            read (tok, *, iostat=ios) v
            ok = ios == 0
        end if
        msg = ''
        if (.not. ok) msg = where(txt, line)//what//': "'//trim(tok)//'" is not an integer'
    end subroutine to_int

    subroutine to_real(txt, line, tok, what, v, ok, msg)
        type(text_t), intent(in) :: txt
        integer, intent(in) :: line
        character(len=*), intent(in) :: tok, what
        real(dp), intent(out) :: v
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        integer :: ios
        v = 0
        ok = len_trim(tok) > 0 .and. verify(trim(tok), '0123456789+-.eEdD') == 0
        if (ok) ok = in_range(trim(tok))
        if (ok) then
            read (tok, *, iostat=ios) v
            ok = ios == 0
            if (ok) ok = ieee_is_finite(v)
        end if
        msg = ''
        if (.not. ok) msg = where(txt, line)//what//': "'//trim(tok)//'" is not a finite number'
    end subroutine to_real

    subroutine positive(txt, line, v, what, ok, msg)
        type(text_t), intent(in) :: txt
        integer, intent(in) :: line
        real(dp), intent(in) :: v
        character(len=*), intent(in) :: what
        logical, intent(out) :: ok
        character(len=*), intent(out) :: msg
        character(len=32) :: b
        ok = v > 0
        msg = ''
        if (.not. ok) then
            write (b, '(es12.5)') v
            msg = where(txt, line)//what//' must be positive, found '//trim(adjustl(b))
        end if
    end subroutine positive

end module terrace_eam_files
