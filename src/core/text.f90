!> Small text helpers shared by the readers.
module terrace_text
    implicit none
    private
    public :: count_tokens

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

end module terrace_text
