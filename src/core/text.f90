!> Small text helpers shared by the readers.
module terrace_text
    use terrace_kinds, only: dp
    implicit none
    private
    public :: count_tokens, fixed, int_text, real_text, sci_text, real_in_format, quoted_list, has_word, &
              style_row

contains

    !> Number of blank-, tab- or comma-separated tokens in a line.
    pure integer function count_tokens(buf) result(n)
        character(len=*), intent(in) :: buf
        integer :: i
        logical :: inside
        n = 0; inside = .false.
        do i = 1, len_trim(buf)
            if (buf(i:i) == ' ' .or. buf(i:i) == achar(9) .or. buf(i:i) == ',') then
                inside = .false.
            else if (.not. inside) then
                inside = .true.; n = n + 1
            end if
        end do
    end function count_tokens

    !> An integer as text, no padding.
    pure function int_text(i) result(s)
        integer, intent(in) :: i
        character(len=:), allocatable :: s
        character(len=16) :: b
        write (b, '(i0)') i
        s = trim(b)
    end function int_text

    !> A real as text with six significant digits (g0.6), no padding.
    function real_text(x) result(s)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: s
        s = real_in_format(x, '(g0.6)')
    end function real_text

    !> A real in scientific notation with four significant digits ('1.000E-12'), no padding.
    function sci_text(x) result(s)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: s
        s = real_in_format(x, '(es10.3)')
    end function sci_text

    !> A real written with the edit descriptor fmt (at most 32 characters), no padding.
    function real_in_format(x, fmt) result(s)
        real(dp), intent(in) :: x
        character(len=*), intent(in) :: fmt
        character(len=:), allocatable :: s
        character(len=32) :: b
        write (b, fmt) x
        s = trim(adjustl(b))
    end function real_in_format

    !> x in fixed notation with d decimals and no padding, with the leading zero that gfortran's
    !> f0.d leaves out ('0.8269', '-0.5', not '.8269', '-.5').
    function fixed(x, d) result(s)
        real(dp), intent(in) :: x
        integer, intent(in) :: d
        character(len=:), allocatable :: s
        character(len=64) :: b, f
        write (f, '(a,i0,a)') '(f0.', d, ')'
        write (b, f) x
        s = trim(adjustl(b))
        if (s(1:1) == '.') then
            s = '0'//s
        else if (len(s) > 1) then
            if (s(1:2) == '-.') s = '-0'//s(2:)
        end if
    end function fixed

    !> The non-blank names (where mask holds) quoted and joined by sep: quoted_list(['a', 'b'], ', ')
    !> is "'a', 'b'" (lists of allowed values in messages).
    pure function quoted_list(names, sep, mask) result(s)
        character(len=*), intent(in) :: names(:), sep
        logical, intent(in), optional :: mask(:)
        character(len=:), allocatable :: s
        integer :: k
        s = ''
        do k = 1, size(names)
            if (len_trim(names(k)) == 0) cycle
            if (present(mask)) then
                if (.not. mask(k)) cycle
            end if
            if (len(s) > 0) s = s//sep
            s = s//"'"//trim(names(k))//"'"
        end do
    end function quoted_list

    !> The row of name in a style table whose row 0 stands for a name no style has: the first k >= 1
    !> with names(k) == name, else 0; a table's record is table(style_row(table%name, name)).
    pure integer function style_row(names, name) result(k)
        character(len=*), intent(in) :: names(0:), name
        k = findloc(names(1:), name, dim=1)
    end function style_row

    !> Whether word is one of the blank-separated words of list.
    elemental logical function has_word(list, word)
        character(len=*), intent(in) :: list, word
        has_word = index(' '//trim(list)//' ', ' '//trim(word)//' ') > 0 .and. len_trim(word) > 0
    end function has_word

end module terrace_text
