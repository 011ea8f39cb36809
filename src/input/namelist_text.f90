!> Splits a namelist file into its groups and `key = value` assignments, with line numbers.
!>
!> Fortran's own namelist READ reports errors without naming the key or the line. Terrace
!> therefore tokenises the file itself: each assignment is later read on its own (as a
!> one-item namelist on an internal file), so that an unknown key, a value of the wrong type or a
!> value out of range is reported with file, line, group and key.
module terrace_namelist_text
    use terrace_kinds, only: i8
    use terrace_text, only: int_text, has_word
    implicit none
    private

    type, public :: assignment_t
        character(len=32) :: group = ''
        character(len=32) :: key = ''                !< base name, lower case, no subscript
        character(len=:), allocatable :: target      !< key as written, with any subscript
        character(len=:), allocatable :: value       !< value text as written
        integer :: line = 0
    end type assignment_t

    type, public :: namelist_file_t
        character(len=:), allocatable :: path
        type(assignment_t), allocatable :: items(:)
        integer :: count = 0
        character(len=32), allocatable :: groups(:)
        integer, allocatable :: group_lines(:)
        integer :: ngroups = 0
        character(len=:), allocatable :: syntax_error  !< empty when the file parsed
    contains
        procedure :: find => nl_find
        procedure :: gives_any => nl_gives_any
        procedure :: where => nl_where
        procedure :: has_group => nl_has_group
    end type namelist_file_t

    public :: parse_namelist_text, lower, at_line, deck_hash

    character(len=*), parameter :: blanks = ' '//achar(9)//achar(10)//achar(13)

contains

    pure function lower(s) result(t)
        character(len=*), intent(in) :: s
        character(len=len(s)) :: t
        integer :: i, c
        t = s
        do i = 1, len(s)
            c = iachar(s(i:i))
            if (c >= iachar('A') .and. c <= iachar('Z')) t(i:i) = achar(c + 32)
        end do
    end function lower

    pure logical function is_name_char(c)
        character, intent(in) :: c
        is_name_char = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z') .or. &
                       (c >= '0' .and. c <= '9') .or. c == '_'
    end function is_name_char

    pure logical function is_space(c)
        character, intent(in) :: c
        is_space = c == ' ' .or. c == achar(9) .or. c == achar(10) .or. c == achar(13)
    end function is_space

    !> Index of the last assignment of group%key, 0 if absent.
    integer function nl_find(self, group, key) result(k)
        class(namelist_file_t), intent(in) :: self
        character(len=*), intent(in) :: group, key
        integer :: i
        k = 0
        do i = 1, self%count
            if (self%items(i)%group == group .and. self%items(i)%key == key) k = i
        end do
    end function nl_find

    !> Does the group give any of the keys (base names, blank-separated: 'pressure damping')?
    logical function nl_gives_any(self, group, keys)
        class(namelist_file_t), intent(in) :: self
        character(len=*), intent(in) :: group, keys
        integer :: i
        nl_gives_any = .false.
        do i = 1, self%count
            if (self%items(i)%group == group .and. has_word(keys, self%items(i)%key)) nl_gives_any = .true.
        end do
    end function nl_gives_any

    !> "file:line: &group: key" for messages (line of the key when it was given).
    function nl_where(self, group, key) result(s)
        class(namelist_file_t), intent(in) :: self
        character(len=*), intent(in) :: group, key
        character(len=:), allocatable :: s
        character(len=16) :: ln
        integer :: k
        k = self%find(group, key)
        if (k > 0) then
            write (ln, '(i0)') self%items(k)%line
            s = self%path//':'//trim(ln)//': &'//trim(group)//': '//trim(key)
        else
            s = self%path//': &'//trim(group)//': '//trim(key)
        end if
    end function nl_where

    logical function nl_has_group(self, group)
        class(namelist_file_t), intent(in) :: self
        character(len=*), intent(in) :: group
        nl_has_group = any(self%groups(1:self%ngroups) == group)
    end function nl_has_group

    subroutine set_error(nf, line, msg)
        type(namelist_file_t), intent(inout) :: nf
        integer, intent(in) :: line
        character(len=*), intent(in) :: msg
        character(len=16) :: ln
        write (ln, '(i0)') line
        if (len(nf%syntax_error) == 0) nf%syntax_error = nf%path//':'//trim(ln)//': '//msg
    end subroutine set_error

    !> Parse the whole text of a namelist file.
    subroutine parse_namelist_text(text, path, nf)
        character(len=*), intent(in) :: text, path
        type(namelist_file_t), intent(out) :: nf
        integer :: i, n, line, start_line, gstart
        character :: c, quote
        character(len=:), allocatable :: body
        integer, allocatable :: body_line(:)
        integer :: nb
        logical :: in_group

        nf%path = path
        nf%syntax_error = ''
        allocate (nf%items(16), nf%groups(8), nf%group_lines(8))
        n = len(text)
        allocate (character(len=n) :: body)
        allocate (body_line(max(n, 1)))
        i = 1; line = 1; in_group = .false.; quote = ' '; nb = 0; start_line = 1
        ! a UTF-8 byte-order mark (editors on Windows save one) is not part of the text
        if (n >= 3) then
            if (text(1:3) == char(239)//char(187)//char(191)) i = 4
        end if
        do while (i <= n)
            c = text(i:i)
            if (.not. in_group) then
                if (c == '!') then
                    do while (i <= n)
                        if (text(i:i) == achar(10)) exit
                        i = i + 1
                    end do
                    cycle
                else if (c == achar(10)) then
                    line = line + 1
                else if (c == '&' .or. c == '$') then
                    gstart = i + 1
                    i = i + 1
                    do while (i <= n)
                        if (.not. is_name_char(text(i:i))) exit
                        i = i + 1
                    end do
                    if (i == gstart) then
                        call set_error(nf, line, "'&' must be followed by a namelist group name")
                        return
                    end if
                    call add_group(nf, lower(text(gstart:i - 1)), line)
                    in_group = .true.; nb = 0; start_line = line
                    cycle
                else if (.not. is_space(c)) then
                    call set_error(nf, line, "text outside a namelist group (groups start with &name and end with /)")
                    return
                end if
                i = i + 1
                cycle
            end if
            ! inside a group
            if (quote /= ' ') then
                if (c == quote) quote = ' '
            else if (c == '"' .or. c == "'") then
                quote = c
            else if (c == '!') then
                do while (i <= n)
                    if (text(i:i) == achar(10)) exit
                    i = i + 1
                end do
                cycle
            else if (c == '/') then
                call split_body(nf, body(1:nb), body_line(1:nb))
                if (len(nf%syntax_error) > 0) return
                in_group = .false.
                i = i + 1
                cycle
            else if (c == '&' .or. c == '$') then
                if (lower(text(i:min(n, i + 3))) == '&end' .or. lower(text(i:min(n, i + 3))) == '$end') then
                    call split_body(nf, body(1:nb), body_line(1:nb))
                    if (len(nf%syntax_error) > 0) return
                    in_group = .false.
                    i = i + 4
                    cycle
                end if
                call set_error(nf, line, "group &"//trim(nf%groups(nf%ngroups))//" is not closed with '/'")
                return
            end if
            nb = nb + 1
            body(nb:nb) = c
            body_line(nb) = line
            if (c == achar(10)) line = line + 1
            i = i + 1
        end do
        if (in_group) then
            call set_error(nf, start_line, "group &"//trim(nf%groups(nf%ngroups))//" is not closed with '/'")
        end if
    end subroutine parse_namelist_text

    subroutine add_group(nf, name, line)
        type(namelist_file_t), intent(inout) :: nf
        character(len=*), intent(in) :: name
        integer, intent(in) :: line
        character(len=32), allocatable :: g(:)
        integer, allocatable :: l(:)
        if (nf%ngroups == size(nf%groups)) then
            allocate (g(2*nf%ngroups), l(2*nf%ngroups))
            g(1:nf%ngroups) = nf%groups; l(1:nf%ngroups) = nf%group_lines
            call move_alloc(g, nf%groups); call move_alloc(l, nf%group_lines)
        end if
        nf%ngroups = nf%ngroups + 1
        nf%groups(nf%ngroups) = name
        nf%group_lines(nf%ngroups) = line
    end subroutine add_group

    !> Split a group body into assignments at every top-level '='.
    subroutine split_body(nf, body, body_line)
        type(namelist_file_t), intent(inout) :: nf
        character(len=*), intent(in) :: body
        integer, intent(in) :: body_line(:)
        integer, allocatable :: key_start(:), eq_pos(:)
        integer :: i, j, depth, neq, k, vend, first, m
        character :: quote
        character(len=:), allocatable :: group
        group = trim(nf%groups(nf%ngroups))
        first = nf%count + 1         ! this group's first assignment
        allocate (key_start(len(body) + 1), eq_pos(len(body) + 1))
        neq = 0; depth = 0; quote = ' '
        do i = 1, len(body)
            if (quote /= ' ') then
                if (body(i:i) == quote) quote = ' '
                cycle
            end if
            select case (body(i:i))
            case ('"', "'")
                quote = body(i:i)
            case ('(')
                depth = depth + 1
            case (')')
                depth = depth - 1
            case ('=')
                if (depth == 0) then
                    neq = neq + 1
                    eq_pos(neq) = i
                    j = i - 1
                    do while (j >= 1)
                        if (.not. is_space(body(j:j))) exit
                        j = j - 1
                    end do
                    if (j >= 1) then
                        if (body(j:j) == ')') then
                            do while (j >= 1)
                                if (body(j:j) == '(') exit
                                j = j - 1
                            end do
                            j = j - 1
                        end if
                    end if
                    k = j
                    do while (j >= 1)
                        if (.not. is_name_char(body(j:j))) exit
                        j = j - 1
                    end do
                    if (k < 1 .or. j == k) then
                        call set_error(nf, body_line(max(1, i)), '&'//group//": '=' without a key name before it")
                        return
                    end if
                    key_start(neq) = j + 1
                end if
            end select
        end do
        if (quote /= ' ') then
            call set_error(nf, body_line(max(1, len(body))), '&'//group//': unterminated string')
            return
        end if
        if (neq == 0) then
            if (verify(body, blanks) > 0) call set_error(nf, body_line(verify(body, blanks)), '&'//group//": expected 'key = value'")
            return
        end if
        if (verify(body(1:key_start(1) - 1), blanks) > 0) then
            call set_error(nf, body_line(verify(body, blanks)), '&'//group//": text before the first 'key = value'")
            return
        end if
        key_start(neq + 1) = len(body) + 1
        do k = 1, neq
            vend = key_start(k + 1) - 1
            do while (vend > eq_pos(k))
                if (.not. (is_space(body(vend:vend)) .or. body(vend:vend) == ',')) exit
                vend = vend - 1
            end do
            call add_item(nf, group, body(key_start(k):eq_pos(k) - 1), body(eq_pos(k) + 1:vend), &
                          body_line(key_start(k)))
            ! a key given twice in one group would silently take its last value
            do m = first, nf%count - 1
                if (compact(nf%items(m)%target) == compact(nf%items(nf%count)%target)) then
                    call set_error(nf, body_line(key_start(k)), '&'//group//': '//compact(nf%items(nf%count)%target)// &
                                   ': given twice in the group (first at line '//int_text(nf%items(m)%line)// &
                                   '); give each key once')
                    return
                end if
            end do
            if (len(stray_word(body(eq_pos(k) + 1:vend))) > 0) then
                call set_error(nf, body_line(key_start(k)), '&'//group//': '//trim(nf%items(nf%count)%key)// &
                               ": unexpected word '"//stray_word(body(eq_pos(k) + 1:vend))// &
                               "' in the value (missing '=' after a key, or quotes around a string?)")
                return
            end if
            if (len_trim(body(eq_pos(k) + 1:vend)) == 0) then
                call set_error(nf, body_line(key_start(k)), '&'//group//': '// &
                               trim(nf%items(nf%count)%key)//': no value after =')
                return
            end if
        end do
    end subroutine split_body

    !> The first unquoted token of a value that starts with a letter, is not a logical literal
    !> (t, f, true, false) nor a non-finite real (nan, inf, infinity: the value check names those)
    !> and has more text after it (as in 'sigma = 1.0 cutoff 2.5'), or ''.
    function stray_word(value) result(w)
        character(len=*), intent(in) :: value
        character(len=:), allocatable :: w
        integer :: i, j
        character :: quote
        w = ''
        quote = ' '
        i = 1
        do while (i <= len(value))
            if (quote /= ' ') then
                if (value(i:i) == quote) quote = ' '
                i = i + 1
                cycle
            end if
            if (value(i:i) == '"' .or. value(i:i) == "'") then
                quote = value(i:i)
                i = i + 1
                cycle
            end if
            if (is_name_char(value(i:i)) .and. .not. (value(i:i) >= '0' .and. value(i:i) <= '9')) then
                if (i > 1) then
                    if (is_name_char(value(i - 1:i - 1)) .or. value(i - 1:i - 1) == '.' .or. &
                        value(i - 1:i - 1) == '+' .or. value(i - 1:i - 1) == '-' .or. value(i - 1:i - 1) == '*') then
                        i = i + 1
                        cycle
                    end if
                end if
                j = i
                do while (j <= len(value))
                    if (.not. is_name_char(value(j:j))) exit
                    j = j + 1
                end do
                select case (lower(value(i:j - 1)))
                case ('t', 'f', 'true', 'false', 'nan', 'inf', 'infinity')
                case default
                    ! a word followed by more text reads as a key without '='; a lone trailing word is
                    ! left to the typed read, which names the expected type
                    if (len_trim(value(j:)) > 0) w = value(i:j - 1)
                    return
                end select
                i = j
                cycle
            end if
            i = i + 1
        end do
    end function stray_word

    subroutine add_item(nf, group, target, value, line)
        type(namelist_file_t), intent(inout) :: nf
        character(len=*), intent(in) :: group, target, value
        integer, intent(in) :: line
        integer :: p
        if (nf%count == size(nf%items)) nf%items = [nf%items, nf%items]   ! full: double it
        nf%count = nf%count + 1
        nf%items(nf%count)%group = group
        nf%items(nf%count)%target = lower(strip(target))
        p = index(nf%items(nf%count)%target, '(')
        if (p == 0) then
            nf%items(nf%count)%key = trim(nf%items(nf%count)%target)
        else
            nf%items(nf%count)%key = trim(nf%items(nf%count)%target(1:p - 1))
        end if
        nf%items(nf%count)%value = strip(value)
        nf%items(nf%count)%line = line
    end subroutine add_item

    !> s without any blanks, tabs or line ends (a key as written: 'velocity(:, 1)' -> 'velocity(:,1)').
    pure function compact(s) result(t)
        character(len=*), intent(in) :: s
        character(len=:), allocatable :: t
        integer :: i
        t = ''
        do i = 1, len(s)
            if (.not. is_space(s(i:i))) t = t//s(i:i)
        end do
    end function compact

    !> s without leading and trailing blanks, tabs and line ends.
    pure function strip(s) result(t)
        character(len=*), intent(in) :: s
        character(len=:), allocatable :: t
        integer :: a, b
        a = verify(s, blanks); b = verify(s, blanks, back=.true.)
        if (a == 0) then
            t = ''
        else
            t = s(a:b)
        end if
    end function strip

    !> 'path:line: ', the prefix of a message about one line of an input ('path: ' for the command line).
    function at_line(path, line) result(s)
        character(len=*), intent(in) :: path
        integer, intent(in) :: line
        character(len=:), allocatable :: s
        character(len=16) :: ln
        write (ln, '(i0)') line
        if (path == '(command line)') then
            s = path//': '
        else
            s = path//':'//trim(ln)//': '
        end if
    end function at_line

    !> A 62-bit hash of the deck's assignments (group, key as written, value as written, in file
    !> order), leaving out those a restart may change: &system read_checkpoint and &run
    !> walltime_limit. Two polynomial hashes modulo primes below 2^31 (no integer overflow).
    integer(i8) function deck_hash(nml) result(h)
        type(namelist_file_t), intent(in) :: nml
        integer(i8), parameter :: p1 = 2147483647_i8, p2 = 2147483629_i8
        integer(i8) :: h1, h2
        integer :: k
        h1 = 7; h2 = 11
        do k = 1, nml%count
            associate (it => nml%items(k))
                if (it%group == 'system' .and. it%key == 'read_checkpoint') cycle
                if (it%group == 'run' .and. it%key == 'walltime_limit') cycle
                if (it%group == 'system' .and. it%key == 'restart_outputs') cycle
                call mix(trim(it%group)//'&'//trim(it%target)//'='//trim(adjustl(it%value))//';')
            end associate
        end do
        h = h1*2147483648_i8 + h2
    contains
        subroutine mix(s)
            character(len=*), intent(in) :: s
            integer :: i
            do i = 1, len(s)
                h1 = mod(h1*131 + ichar(s(i:i)), p1)
                h2 = mod(h2*257 + ichar(s(i:i)), p2)
            end do
        end subroutine mix
    end function deck_hash

end module terrace_namelist_text
