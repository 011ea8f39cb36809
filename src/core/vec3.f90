!> Small 3-vector helpers.
module terrace_vec3
    use terrace_kinds, only: dp
    implicit none
    private
    public :: cross

contains

    pure function cross(a, b) result(c)
        real(dp), intent(in) :: a(3), b(3)
        real(dp) :: c(3)
        c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
    end function cross

end module terrace_vec3
