!> Counter-based random numbers: Philox4x32-10 (Salmon, Moraes, Dror & Shaw, "Parallel random
!> numbers: as easy as 1, 2, 3", SC'11), written from the published algorithm.
!>
!> A block of four 32-bit words is a pure function of a 128-bit counter c and a 64-bit key k:
!>   ten rounds of  (hi0, lo0) = M0 * c0,  (hi1, lo1) = M1 * c2  (32 x 32 -> 64-bit products),
!>                  c <- (hi1 xor c1 xor k0, lo1, hi0 xor c3 xor k1, lo0),
!>   with the key bumped by the Weyl increments (W0, W1) mod 2^32 before rounds 2..10.
!> Fortran has no unsigned integers: every word is held in an integer(int64) in [0, 2^32) and the
!> products are formed from 16-bit halves so that nothing exceeds 2^63.
!>
!> Terrace keys its draws by what they are for, never by where they are computed, so a run gives
!> the same numbers on any rank count and after a restart:
!>   key     = (seed mod 2^32, (seed div 2^32 + stream * 0x9E3779B1) mod 2^32)
!>   counter = (sub, id mod 2^32, id div 2^32 mod 2^16 + 2^16 (event mod 2^16), event div 2^16 mod 2^32)
!> with stream naming the purpose (Langevin noise, Andersen times, ...), id the atom id (or 0 for a
!> global draw), event the step or event number and sub the block index within that draw. Ids and
!> events must stay below 2^48.
!>
!> Derived variates: uniform doubles in (0, 1) from two words (53 bits) or from one word (32 bits,
!> the fast path of the per-atom kernels), standard normals by Box-Muller, exponentials -ln u, and
!> Gamma(a, 1) by Marsaglia & Tsang (2000) (a < 1: Gamma(a + 1) u^(1/a)); chi-square(n) = 2 Gamma(n/2).
!>
!> The per-atom batch kernels (rng_blocks, normals3_many) are the cost of a stochastic thermostat:
!> they are written so that gfortran vectorises them across atoms: Philox's words held in 64-bit
!> lanes, each product one unsigned 32 x 32 -> 64-bit multiply (eight counters per AVX-512
!> vector), and the three Langevin normals of an atom by a branch-free single-precision
!> Box-Muller (box_muller3_batch: sixteen lanes, polynomials instead of the library's scalar log,
!> sin and cos; within 1e-6 of the double-precision transform). Fortran has no unsigned type: the
!> words wrap modulo 2^32, so this file is compiled with -fwrapv (and -fno-trapping-math, which
!> lets the selects be if-converted); see CMakeLists.txt.
module terrace_counter_rng
    use terrace_kinds, only: dp, i8
    use, intrinsic :: iso_fortran_env, only: i4 => int32, sp => real32
    implicit none
    private

    integer(i8), parameter :: mask32 = 4294967295_i8, mask16 = 65535_i8
    integer(i8), parameter :: philox_m0 = 3528531795_i8    ! 0xD2511F53
    integer(i8), parameter :: philox_m1 = 3449720151_i8    ! 0xCD9E8D57
    integer(i8), parameter :: philox_w0 = 2654435769_i8    ! 0x9E3779B9
    integer(i8), parameter :: philox_w1 = 3144134277_i8    ! 0xBB67AE85
    integer(i8), parameter :: stream_mix = 2654435761_i8   ! 0x9E3779B1
    integer(i8), parameter :: m0_lo = iand(philox_m0, mask16), m0_hi = ishft(philox_m0, -16)  ! 16-bit halves
    integer(i8), parameter :: m1_lo = iand(philox_m1, mask16), m1_hi = ishft(philox_m1, -16)
    real(dp), parameter :: two_pi = 8*atan(1.0_dp), sqrt_2 = 1.4142135623730950488_dp
    real(dp), parameter :: inv_2_32 = 1.0_dp/4294967296.0_dp, inv_2_53 = 1.0_dp/9007199254740992.0_dp

    !> A sequence of draws for one (seed, stream, id, event): blocks sub = 0, 1, 2, ... consumed
    !> word by word. Small, so it lives on the stack of the loop that uses it.
    type, public :: rng_stream_t
        integer(i8) :: key(2) = 0, ctr(4) = 0
        integer(i8) :: words(4) = 0
        integer :: used = 4                  !< words of the current block consumed
        logical :: have_normal = .false.
        real(dp) :: spare_normal = 0
    contains
        procedure :: uniform => stream_uniform
        procedure :: normal => stream_normal
        procedure :: exponential => stream_exponential
        procedure :: gamma => stream_gamma
        procedure :: chi_square => stream_chi_square
    end type rng_stream_t

    public :: philox4x32_10, rng_key, rng_counter, rng_block, rng_stream, unit_from_word, unit_from_words
    public :: normals3, box_muller, rng_blocks, normals3_many, box_muller3_batch

    integer, parameter, public :: rng_batch = 64   !< atoms per batch of the vectorised kernels

contains

    !> Upper and lower 32 bits of a*b, a and b in [0, 2^32): b split in 16-bit halves keeps the
    !> partial products below 2^48.
    elemental subroutine mulhilo(a, b, hi, lo)
        integer(i8), intent(in) :: a, b
        integer(i8), intent(out) :: hi, lo
        integer(i8) :: p0, p1, t
        p0 = a*iand(b, mask16)
        p1 = a*ishft(b, -16)
        t = p0 + ishft(iand(p1, mask16), 16)
        lo = iand(t, mask32)
        hi = ishft(p1, -16) + ishft(t, -32)
    end subroutine mulhilo

    !> Philox4x32 with ten rounds: the 4-word block for counter ctr and key key (words in [0, 2^32)).
    !> The reference form (64-bit products from 16-bit halves; the known-answer vectors are tested
    !> on it); the draws use philox_block, its fast scalar twin (the same words, unit-tested).
    pure function philox4x32_10(ctr, key) result(c)
        integer(i8), intent(in) :: ctr(4), key(2)
        integer(i8) :: c(4)
        integer(i8) :: k0, k1, hi0, lo0, hi1, lo1
        integer :: r
        c = ctr
        k0 = key(1); k1 = key(2)
        do r = 1, 10
            if (r > 1) then
                k0 = iand(k0 + philox_w0, mask32)
                k1 = iand(k1 + philox_w1, mask32)
            end if
            call mulhilo(philox_m0, c(1), hi0, lo0)
            call mulhilo(philox_m1, c(3), hi1, lo1)
            c = [ieor(ieor(hi1, c(2)), k0), lo1, ieor(ieor(hi0, c(4)), k1), lo0]
        end do
    end function philox4x32_10

    !> philox4x32_10 through the rounds of the batch kernels (about a third of the instructions):
    !> the block of one counter for rng_block and the streams.
    pure function philox_block(ctr, key) result(c)
        integer(i8), intent(in) :: ctr(4), key(2)
        integer(i8) :: c(4)
        integer(i8) :: k0(10), k1(10)
        call round_keys(key, k0, k1)
        c = ctr
        call philox_rounds(k0, k1, c(1), c(2), c(3), c(4))
    end function philox_block

    !> Philox4x32-10 on n counters at once (c(:, 1..4) in place; the same key): the same words as
    !> philox4x32_10 counter by counter, through the vectorised rounds of philox_rounds.
    pure subroutine rng_blocks(n, c, key)
        integer, intent(in) :: n
        integer(i8), intent(inout) :: c(n, 4)
        integer(i8), intent(in) :: key(2)
        integer(i8) :: k0(10), k1(10)
        integer :: i
        call round_keys(key, k0, k1)
        do i = 1, n
            call philox_rounds(k0, k1, c(i, 1), c(i, 2), c(i, 3), c(i, 4))
        end do
    end subroutine rng_blocks

    !> The ten round keys (k0, k1) of key (words in [0, 2^32)).
    pure subroutine round_keys(key, k0, k1)
        integer(i8), intent(in) :: key(2)
        integer(i8), intent(out) :: k0(10), k1(10)
        integer :: r
        k0(1) = key(1); k1(1) = key(2)
        do r = 2, 10
            k0(r) = iand(k0(r - 1) + philox_w0, mask32)
            k1(r) = iand(k1(r - 1) + philox_w1, mask32)
        end do
    end subroutine round_keys

    !> The ten Philox rounds on one counter (x0..x3 in place, words in [0, 2^32) held in 64-bit
    !> lanes). Written for the vectoriser (inlined into loops over counters): a word times a
    !> multiplier below 2^32 is one unsigned 32 x 32 -> 64-bit product (vpmuludq), which wraps past
    !> 2^63, so this file is compiled with -fwrapv; the high half is the product shifted, the low
    !> half the product masked. Keeping the words in 64-bit lanes spares the widening and narrowing
    !> of every round (about 30 % faster than int32 words on AVX-512).
    pure subroutine philox_rounds(k0, k1, x0, x1, x2, x3)
        integer(i8), intent(in) :: k0(10), k1(10)
        integer(i8), intent(inout) :: x0, x1, x2, x3
        integer(i8) :: p0, p1
        integer :: r
!GCC$ unroll 10
        do r = 1, 10
            p0 = x0*philox_m0
            p1 = x2*philox_m1
            x0 = ieor(ieor(ishft(p1, -32), x1), k0(r))
            x2 = ieor(ieor(ishft(p0, -32), x3), k1(r))
            x1 = iand(p1, mask32); x3 = iand(p0, mask32)
        end do
    end subroutine philox_rounds

    !> Three standard normals for each of n <= rng_batch ids: z(i, 1..3) from the block of (seed, stream, ids(i),
    !> event, 0), the numbers of the Langevin noise. Two vectorised loops: the Philox blocks (64-bit
    !> lanes), then single-precision Box-Muller on the block's words (box_muller3_batch). The
    !> numbers of an id do not depend on n or on its place in the batch (the vector and the
    !> remainder code agree bitwise, unit-tested), so a batch of one is the scalar twin.
    pure subroutine normals3_many(n, seed, stream, ids, event, z)
        integer, intent(in) :: n, stream
        integer(i8), intent(in) :: seed, ids(n), event
        real(dp), intent(out) :: z(n, 3)
        integer(i8) :: k0(10), k1(10), ev_lo, ev_hi, x0, x1, x2, x3
        integer(i4) :: c1(rng_batch), c2(rng_batch), wr(rng_batch, 2), wa(rng_batch, 2)
        integer :: i
        call round_keys(rng_key(seed, stream), k0, k1)
        ev_lo = ishft(iand(event, mask16), 16)
        ev_hi = iand(ishft(event, -16), mask32)
        ! the counters' id words first, as int32 patterns (a loop of their own: the vectoriser takes
        ! the rounds' loop only with 32-bit loads)
        do i = 1, n
            c1(i) = int(iand(ids(i), mask32), i4)
            c2(i) = int(ior(iand(ishft(ids(i), -32), mask16), ev_lo), i4)
        end do
        do i = 1, n
            x0 = 0; x1 = iand(int(c1(i), i8), mask32); x2 = iand(int(c2(i), i8), mask32); x3 = ev_hi
            call philox_rounds(k0, k1, x0, x1, x2, x3)
            wr(i, 1) = int(x0, i4); wr(i, 2) = int(x2, i4)
            wa(i, 1) = int(x1, i4); wa(i, 2) = int(x3, i4)
        end do
        call box_muller3_batch(n, wr, wa, z)
    end subroutine normals3_many

    !> Three standard normals per row (n <= rng_batch rows) from four 32-bit words (int32 patterns):
    !> radius words wr(i, 1:2), angle words wa(i, 1:2); z(i, :) = (r1 cos a1, r1 sin a1, r2 cos a2).
    !> Single precision, 16 lanes on AVX-512 (the normals are noise: 24 bits are plenty), each
    !> loop branch-free:
    !>   r = sqrt(-2 ln u), u = (w + 1/2) 2^-32 (tails cut at |z| = 6.77, a probability of 1e-10):
    !>   ln u = e ln 2 + 2 atanh(s), s = (m - 1)/(m + 1) from u = m 2^e, m in [sqrt(1/2), sqrt(2)),
    !>   or s = -v/(2 - v) from v = 1 - u, formed exactly from the complement of the word, when
    !>   u > sqrt(1/2) (so that ln u keeps its relative precision as u -> 1); |s| < 0.172 and the
    !>   atanh series to s^9 (truncation below 1e-9);
    !>   the angle 2 pi (w + 1/2) 2^-32 = k pi/2 + t, k the nearest quarter turn and |t| <= pi/4
    !>   from the word's integer bits; sin t and cos t by their Taylor polynomials to t^9 and t^10
    !>   (truncation below 2e-9).
    !> Within 1e-6 max(1, |z|) of box_muller on the same uniforms in double precision (unit-tested).
    pure subroutine box_muller3_batch(n, wr, wa, z)
        integer, intent(in) :: n
        integer(i4), intent(in) :: wr(rng_batch, 2), wa(rng_batch, 2)
        real(dp), intent(out) :: z(n, 3)
        integer(i4), parameter :: mant_mask = 8388607_i4, one_bits = 1065353216_i4
        real(sp), parameter :: ln2 = 0.693147180559945309_sp, sqrt_2_sp = 1.41421356_sp, two32 = 4294967296.0_sp
        real(sp), parameter :: inv32 = 1.0_sp/4294967296.0_sp, half32 = 0.5_sp/4294967296.0_sp
        real(sp), parameter :: per_unit = 6.28318530717958648_sp/4294967296.0_sp
        real(sp) :: r(rng_batch, 2), c(rng_batch, 2), s(rng_batch, 2), u, v, m, e, x, x2, y, t, t2, sn, cs
        integer(i4) :: b, q, k, j
        logical :: near1
        integer :: i, h
        do h = 1, 2
        do i = 1, n
            b = wr(i, h)
            u = (real(b, sp) + merge(two32, 0.0_sp, b < 0))*inv32 + half32
            j = not(b)
            v = (real(j, sp) + merge(two32, 0.0_sp, j < 0))*inv32 + half32
            b = transfer(u, b)
            e = real(ishft(b, -23) - 127_i4, sp)
            m = transfer(ior(iand(b, mant_mask), one_bits), m)
            e = e + merge(1.0_sp, 0.0_sp, m > sqrt_2_sp)
            m = merge(0.5_sp*m, m, m > sqrt_2_sp)
            near1 = v < 0.29289322_sp
            x = merge(-v, m - 1, near1)/merge(2 - v, m + 1, near1)
            e = merge(0.0_sp, e, near1)
            x2 = x*x
            y = 1.0_sp/9
            y = y*x2 + 1.0_sp/7
            y = y*x2 + 1.0_sp/5
            y = y*x2 + 1.0_sp/3
            y = (y*x2)*x + x
            r(i, h) = sqrt(max(-2*(e*ln2 + 2*y), 0.0_sp))
        end do
        end do
        do h = 1, 2
        do i = 1, n
            q = wa(i, h) + 536870912_i4
            k = iand(ishft(q, -30), 3_i4)
            t = (real(iand(q, 1073741823_i4) - 536870912_i4, sp) + 0.5_sp)*per_unit
            t2 = t*t
            sn = 1.0_sp/362880
            sn = sn*t2 - 1.0_sp/5040
            sn = sn*t2 + 1.0_sp/120
            sn = sn*t2 - 1.0_sp/6
            sn = (sn*t2)*t + t
            cs = -1.0_sp/3628800
            cs = cs*t2 + 1.0_sp/40320
            cs = cs*t2 - 1.0_sp/720
            cs = cs*t2 + 1.0_sp/24
            cs = cs*t2 - 0.5_sp
            cs = cs*t2 + 1
            c(i, h) = merge(-1.0_sp, 1.0_sp, iand(k + 1_i4, 2_i4) /= 0)*merge(sn, cs, iand(k, 1_i4) == 1)
            s(i, h) = merge(-1.0_sp, 1.0_sp, iand(k, 2_i4) /= 0)*merge(cs, sn, iand(k, 1_i4) == 1)
        end do
        end do
        do i = 1, n
            z(i, 1) = real(r(i, 1)*c(i, 1), dp)
            z(i, 2) = real(r(i, 1)*s(i, 1), dp)
            z(i, 3) = real(r(i, 2)*c(i, 2), dp)
        end do
    end subroutine box_muller3_batch

    !> The key of (seed, stream).
    pure function rng_key(seed, stream) result(key)
        integer(i8), intent(in) :: seed
        integer, intent(in) :: stream
        integer(i8) :: key(2)
        key(1) = iand(seed, mask32)
        key(2) = iand(ishft(seed, -32) + iand(int(stream, i8)*stream_mix, mask32), mask32)
    end function rng_key

    !> The counter of (id, event, sub).
    pure function rng_counter(id, event, sub) result(ctr)
        integer(i8), intent(in) :: id, event
        integer, intent(in) :: sub
        integer(i8) :: ctr(4)
        ctr(1) = iand(int(sub, i8), mask32)
        ctr(2) = iand(id, mask32)
        ctr(3) = ior(iand(ishft(id, -32), mask16), ishft(iand(event, mask16), 16))
        ctr(4) = iand(ishft(event, -16), mask32)
    end function rng_counter

    !> Four words for (seed, stream, id, event, sub).
    pure function rng_block(seed, stream, id, event, sub) result(w)
        integer(i8), intent(in) :: seed, id, event
        integer, intent(in) :: stream, sub
        integer(i8) :: w(4)
        w = philox_block(rng_counter(id, event, sub), rng_key(seed, stream))
    end function rng_block

    !> A word as a uniform double in (0, 1) (32-bit resolution; never 0 or 1).
    elemental real(dp) function unit_from_word(w) result(u)
        integer(i8), intent(in) :: w
        u = (real(w, dp) + 0.5_dp)*inv_2_32
    end function unit_from_word

    !> Two words as a uniform double in (0, 1) with 53 random bits (never 0 or 1).
    elemental real(dp) function unit_from_words(w1, w2) result(u)
        integer(i8), intent(in) :: w1, w2
        u = (real(ior(ishft(w1, 21), ishft(w2, -11)), dp) + 0.5_dp)*inv_2_53
    end function unit_from_words

    !> Two standard normals from two uniforms in (0, 1) (Box-Muller).
    pure subroutine box_muller(u1, u2, z1, z2)
        real(dp), intent(in) :: u1, u2
        real(dp), intent(out) :: z1, z2
        real(dp) :: r
        r = sqrt(-2*log(u1))
        z1 = r*cos(two_pi*u2)
        z2 = r*sin(two_pi*u2)
    end subroutine box_muller

    !> Three standard normals of (seed, stream, id, event): normals3_many for one id, bitwise the
    !> batch kernel's numbers.
    pure subroutine normals3(seed, stream, id, event, z)
        integer(i8), intent(in) :: seed, id, event
        integer, intent(in) :: stream
        real(dp), intent(out) :: z(3)
        real(dp) :: zz(1, 3)
        call normals3_many(1, seed, stream, [id], event, zz)
        z = zz(1, :)
    end subroutine normals3

    !> The draw sequence of (seed, stream, id, event).
    pure function rng_stream(seed, stream, id, event) result(s)
        integer(i8), intent(in) :: seed, id, event
        integer, intent(in) :: stream
        type(rng_stream_t) :: s
        s%key = rng_key(seed, stream)
        s%ctr = rng_counter(id, event, 0)
        s%used = 4
    end function rng_stream

    pure subroutine next_word(s, w)
        class(rng_stream_t), intent(inout) :: s
        integer(i8), intent(out) :: w
        if (s%used == 4) then
            s%words = philox_block(s%ctr, s%key)
            s%ctr(1) = iand(s%ctr(1) + 1, mask32)
            s%used = 0
        end if
        s%used = s%used + 1
        w = s%words(s%used)
    end subroutine next_word

    !> Uniform in (0, 1), 53 bits.
    real(dp) function stream_uniform(s) result(u)
        class(rng_stream_t), intent(inout) :: s
        integer(i8) :: w1, w2
        call next_word(s, w1)
        call next_word(s, w2)
        u = unit_from_words(w1, w2)
    end function stream_uniform

    !> Standard normal (Box-Muller on 53-bit uniforms, the second value kept for the next call).
    real(dp) function stream_normal(s) result(z)
        class(rng_stream_t), intent(inout) :: s
        real(dp) :: u1, u2, z2
        if (s%have_normal) then
            s%have_normal = .false.
            z = s%spare_normal
            return
        end if
        u1 = s%uniform()
        u2 = s%uniform()
        call box_muller(u1, u2, z, z2)
        s%spare_normal = z2
        s%have_normal = .true.
    end function stream_normal

    !> Exponential with mean 1.
    real(dp) function stream_exponential(s) result(e)
        class(rng_stream_t), intent(inout) :: s
        e = -log(s%uniform())
    end function stream_exponential

    !> Gamma(a, 1), a > 0: Marsaglia & Tsang's squeeze on (1 + c z)^3 (a >= 1), boosted for a < 1.
    real(dp) function stream_gamma(s, a) result(g)
        class(rng_stream_t), intent(inout) :: s
        real(dp), intent(in) :: a
        real(dp) :: d, c, z, v, u, boost
        boost = 1
        d = a
        if (a < 1) then
            boost = s%uniform()**(1/a)
            d = a + 1
        end if
        d = d - 1.0_dp/3
        c = 1/sqrt(9*d)
        do
            z = s%normal()
            v = 1 + c*z
            if (v <= 0) cycle
            v = v*v*v
            u = s%uniform()
            if (u < 1 - 0.0331_dp*z**4) exit
            if (log(u) < 0.5_dp*z*z + d*(1 - v + log(v))) exit
        end do
        g = d*v*boost
    end function stream_gamma

    !> Chi-square with n degrees of freedom: the sum of n squared standard normals.
    real(dp) function stream_chi_square(s, n) result(x)
        class(rng_stream_t), intent(inout) :: s
        integer(i8), intent(in) :: n
        real(dp) :: z
        select case (n)
        case (:0)
            x = 0
        case (1)
            z = s%normal()
            x = z*z
        case default
            x = 2*s%gamma(0.5_dp*real(n, dp))
        end select
    end function stream_chi_square

end module terrace_counter_rng
