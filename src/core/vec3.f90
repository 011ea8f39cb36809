!> Small 3-vector helpers.
module terrace_vec3
    use terrace_kinds, only: dp
    implicit none
    private
    public :: cross, add_scaled, fill_zero

contains

    pure function cross(a, b) result(c)
        real(dp), intent(in) :: a(3), b(3)
        real(dp) :: c(3)
        c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
    end function cross

    !> x(1:n) = x(1:n) + s v(1:n) over flat arrays: a 3 x N array of positions or velocities passed
    !> whole (sequence association) is one contiguous loop. Written as x(:, 1:m) = x(:, 1:m) +
    !> s v(:, 1:m), GCC made two nested loops with an inner one of run-time extent 3 (scalar, a test per atom).
    pure subroutine add_scaled(n, s, v, x)
        integer, intent(in) :: n
        real(dp), intent(in) :: s, v(*)
        real(dp), intent(inout) :: x(*)
        integer :: k
        do k = 1, n
            x(k) = x(k) + s*v(k)
        end do
    end subroutine add_scaled

    !> x(1:n) = 0 over a flat array, one fill: a 3 x N array passed whole (sequence association).
    !> Written as x(:, 1:m) = 0, GCC called memset once per column of three values.
    pure subroutine fill_zero(n, x)
        integer, intent(in) :: n
        real(dp), intent(inout) :: x(*)
        x(1:n) = 0
    end subroutine fill_zero

end module terrace_vec3
