!> Global sums that do not depend on the order of the terms nor on how they are spread over the
!> ranks (the same bits on 1, 2 or 4 ranks): each term t is cut on three fixed binary grids,
!>   t = a1 q1 + a2 q2 + a3 q3 + r,   q_l = 2^(e - l L),  a_l integers with |a_l| <= 2^L,
!> e the exponent of the largest |term| on any rank (MPI_MAX: exact), L = 52 - ceil(log2(N + 1))
!> bits for N terms in all. Integer-valued doubles below 2^52 add exactly in any order, so the
!> per-rank sums of a_l are exact; they travel as 64-bit integers (MPI_SUM: exact) and the total
!> is rebuilt as K1 q1 + K2 q2 + K3 q3. The cut-off r is below 2^(e - 3L - 1) per term (3L >= 114
!> bits below the largest term for up to 2^14 terms per 38-bit level): far finer than the round-off
!> of a plain sum. Non-finite terms, or a scale out of range: a plain (order-dependent) sum.
!> Costs one MPI_Allreduce(MAX) and one MPI_Allreduce(SUM) of 3 integers per quantity; none on
!> one rank.
module terrace_exact_sum
    use terrace_kinds, only: dp, i8
    use terrace_mpi_env, only: world
    use mpi_f08, only: MPI_Allreduce, MPI_IN_PLACE, MPI_DOUBLE_PRECISION, MPI_INTEGER8, MPI_SUM, MPI_MAX
    implicit none
    private

    integer, parameter :: nlevel = 3
    integer, parameter :: max_quantities = 8
    integer, parameter :: nlane = 8                  !< independent partial sums (vectorised)
    real(dp), parameter :: magic = 1.5_dp*2.0_dp**52

    public :: exact_sum_all

contains

    !> total(c) = sum over all ranks of terms(1:n, c), c = 1..size(total) (at most 8), the same
    !> bits whatever the order or the partition of the nglobal terms over the ranks. With
    !> reduce = .false. only this rank's terms are summed (same arithmetic, no MPI call).
    subroutine exact_sum_all(terms, n, nglobal, total, reduce)
        real(dp), intent(in), contiguous :: terms(:, :)
        integer, intent(in) :: n
        integer(i8), intent(in) :: nglobal
        real(dp), intent(out) :: total(:)
        logical, intent(in) :: reduce
        real(dp) :: m(max_quantities), acc(nlevel), q(nlevel), rq(nlevel), z, mv(nlane), zv(nlane), &
                    av1(nlane), av2(nlane), av3(nlane), r, a1, a2, a3
        integer(i8) :: kint(nlevel, max_quantities)
        logical :: plain(max_quantities)
        integer :: nq, c, i, l, lbits, e, nb
        nq = size(total)
        nb = (n/nlane)*nlane
        do c = 1, nq
            ! largest |term|, and z = sum of 0 t: NaN if a term is NaN or Inf (vectorised, no branch)
            mv = 0; zv = 0
            do i = 1, nb, nlane
                do l = 1, nlane
                    mv(l) = max(mv(l), abs(terms(i + l - 1, c)))
                    zv(l) = zv(l) + 0*terms(i + l - 1, c)
                end do
            end do
            do i = nb + 1, n
                mv(1) = max(mv(1), abs(terms(i, c)))
                zv(1) = zv(1) + 0*terms(i, c)
            end do
            m(c) = maxval(mv)
            z = sum(zv)
            ! NaN or Inf: flag with the largest finite value, so that every rank takes the plain path
            if (.not. (z == 0 .and. m(c) <= huge(1.0_dp))) m(c) = huge(1.0_dp)
        end do
        if (reduce .and. world%nprocs > 1) call MPI_Allreduce(MPI_IN_PLACE, m, nq, MPI_DOUBLE_PRECISION, MPI_MAX, world%comm)
        lbits = 52 - ceiling(log(real(nglobal + 1, dp))/log(2.0_dp))
        lbits = max(8, min(40, lbits))
        kint = 0
        do c = 1, nq
            e = exponent(m(c))
            plain(c) = m(c) >= huge(1.0_dp) .or. e - nlevel*lbits < minexponent(1.0_dp) + 60 .or. &
                       e > maxexponent(1.0_dp) - 4
            if (m(c) == 0) then
                plain(c) = .false.
                cycle
            end if
            if (plain(c)) then
                total(c) = sum(terms(1:n, c))
                cycle
            end if
            do i = 1, nlevel
                q(i) = scale(1.0_dp, e - i*lbits)
                rq(i) = scale(1.0_dp, i*lbits - e)
            end do
            av1 = 0; av2 = 0; av3 = 0
            do i = 1, nb, nlane
                do l = 1, nlane
                    ! (x + 1.5 2^52) - 1.5 2^52 is x rounded to an integer for |x| <= 2^40; the
                    ! products are exact, so a fused multiply-add gives the same bits
                    r = terms(i + l - 1, c)
                    a1 = (r*rq(1) + magic) - magic
                    r = r - a1*q(1)
                    a2 = (r*rq(2) + magic) - magic
                    r = r - a2*q(2)
                    a3 = (r*rq(3) + magic) - magic
                    av1(l) = av1(l) + a1
                    av2(l) = av2(l) + a2
                    av3(l) = av3(l) + a3
                end do
            end do
            do i = nb + 1, n
                r = terms(i, c)
                a1 = (r*rq(1) + magic) - magic
                r = r - a1*q(1)
                a2 = (r*rq(2) + magic) - magic
                r = r - a2*q(2)
                a3 = (r*rq(3) + magic) - magic
                av1(1) = av1(1) + a1
                av2(1) = av2(1) + a2
                av3(1) = av3(1) + a3
            end do
            ! integer-valued partial sums below 2^52: exact, so the lanes add up in any order
            acc = [sum(av1), sum(av2), sum(av3)]
            kint(:, c) = int(acc, i8)
        end do
        if (reduce .and. world%nprocs > 1) then
            call MPI_Allreduce(MPI_IN_PLACE, kint, nlevel*nq, MPI_INTEGER8, MPI_SUM, world%comm)
            do c = 1, nq
                if (plain(c)) call MPI_Allreduce(MPI_IN_PLACE, total(c), 1, MPI_DOUBLE_PRECISION, MPI_SUM, world%comm)
            end do
        end if
        do c = 1, nq
            if (plain(c)) cycle
            if (m(c) == 0) then
                total(c) = 0
                cycle
            end if
            e = exponent(m(c))
            total(c) = (real(kint(1, c), dp)*scale(1.0_dp, e - lbits) + real(kint(2, c), dp)*scale(1.0_dp, e - 2*lbits)) &
                       + real(kint(3, c), dp)*scale(1.0_dp, e - 3*lbits)
        end do
    end subroutine exact_sum_all

end module terrace_exact_sum
