!> The velocity jump of energy stepping at a terrace edge, as a pure function of the global sums
!> a = mvv2e sum |g_i|^2/m_i and b = mvv2e sum g_i.v_i (g = grad V) and the terrace height h:
!> v_i += lambda g_i/m_i with lambda the root of a lambda^2 + 2 b lambda + 2 dV = 0 that keeps the
!> sign of the normal velocity b + lambda a (cancellation-free forms):
!>   climb  (b > 0, b^2 >= 2 a h): lambda = -2h / (b + sqrt(b^2 - 2 a h)),  dk = +1
!>   reflect (b^2 < 2 a h):        lambda = -2b / a,                        dk =  0
!>   fall   (b < 0):               lambda = -2h / (|b| + sqrt(b^2 + 2 a h)), dk = -1
module terrace_jump
    use terrace_kinds, only: dp
    implicit none
    private

    integer, parameter, public :: jump_climb = 1, jump_reflect = 0, jump_fall = -1, jump_none = 2

    public :: terrace_jump_lambda

contains

    !> upward: the crossing is of the upper edge (else the lower one). outcome is jump_none when
    !> the normal velocity does not point across the edge (b <= 0 going up, b >= 0 going down).
    pure subroutine terrace_jump_lambda(a, b, h, upward, lambda, outcome)
        real(dp), intent(in) :: a, b, h
        logical, intent(in) :: upward
        real(dp), intent(out) :: lambda
        integer, intent(out) :: outcome
        real(dp) :: disc
        lambda = 0
        if (upward) then
            if (.not. (b > 0)) then
                outcome = jump_none
                return
            end if
            disc = b*b - 2*a*h
            if (disc >= 0) then
                lambda = -2*h/(b + sqrt(disc))
                outcome = jump_climb
            else
                lambda = -2*b/a
                outcome = jump_reflect
            end if
        else
            if (.not. (b < 0)) then
                outcome = jump_none
                return
            end if
            lambda = -2*h/(-b + sqrt(b*b + 2*a*h))
            outcome = jump_fall
        end if
    end subroutine terrace_jump_lambda

end module terrace_jump
