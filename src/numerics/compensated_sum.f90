!> Compensated sums: the total of many terms with the round-off of every addition carried along
!> (Knuth's TwoSum: for t = s + x rounded, with z = t - s, the error (s - (t - z)) + (x - z) is
!> exact; no branch, and no product for a contracted FMA to change). The error of the result is
!> about one rounding of the total instead of the random walk of a plain running sum.
!>
!> Why it matters: the energy-stepping event solver decides on V, the total potential energy of
!> all atoms, to a tolerance of a few tens of eps |V| (root_tolerance h, or 64 eps |V| when that is
!> larger). A plain running sum of the ~30 N pair energies of N atoms rounds each addition to half
!> an ulp of the partial sum, which is of the size of |V|: a noise of about sqrt(30 N) ulp(|V|)/sqrt(12)
!> that changes at random with every change of the positions (32,000 LJ atoms: ~5e-9, twice the
!> tolerance). The pair kernels therefore sum each atom's own pairs plainly (a few terms, each
!> rounded to the atom's own size) and total the per-atom sums here.
module terrace_compensated_sum
    use terrace_kinds, only: dp
    implicit none
    private

    integer, parameter :: nlane = 8        !< independent compensated partial sums (vectorised)

    public :: compensated_total, comp_add

contains

    !> s + c += x (c holds the round-off of the additions so far; the total is s + c).
    elemental subroutine comp_add(s, c, x)
        real(dp), intent(inout) :: s, c
        real(dp), intent(in) :: x
        real(dp) :: t, z
        t = s + x
        z = t - s
        c = c + ((s - (t - z)) + (x - z))
        s = t
    end subroutine comp_add

    !> sum(x(1:n)), compensated: nlane interleaved TwoSum accumulators, then combined in a fixed
    !> order (the result depends only on the terms and their order).
    pure real(dp) function compensated_total(x, n) result(total)
        real(dp), intent(in) :: x(*)
        integer, intent(in) :: n
        real(dp) :: s(nlane), c(nlane), t(nlane), z(nlane), st, ct
        integer :: i, l, nb
        s = 0; c = 0
        nb = (n/nlane)*nlane
        do i = 1, nb, nlane
            do l = 1, nlane
                t(l) = s(l) + x(i + l - 1)
                z(l) = t(l) - s(l)
                c(l) = c(l) + ((s(l) - (t(l) - z(l))) + (x(i + l - 1) - z(l)))
                s(l) = t(l)
            end do
        end do
        st = 0; ct = 0
        do l = 1, nlane
            call comp_add(st, ct, s(l))
        end do
        do i = nb + 1, n
            call comp_add(st, ct, x(i))
        end do
        total = st + (ct + sum(c))
    end function compensated_total

end module terrace_compensated_sum
