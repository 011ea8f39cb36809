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
!> The per-atom batch kernels (rng_blocks, normals4_many) are the cost of a stochastic thermostat:
!> they are written so that gfortran vectorises them across atoms (AVX2: four or eight counters at
!> a time): 32-bit words held as int32 patterns, each Philox product one unsigned 32 x 32 -> 64-bit
!> multiply, Box-Muller by branch-free polynomials (box_muller_batch) rather than the
!> library's scalar log/sin/cos. Fortran has no unsigned type: the words wrap modulo 2^32, so this
!> file is compiled with -fwrapv (and -fno-trapping-math, which lets the selects be if-converted);
!> see CMakeLists.txt.
module terrace_counter_rng
    use terrace_kinds, only: dp, i8
    use, intrinsic :: iso_fortran_env, only: i4 => int32
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
    public :: normals4, box_muller, rng_blocks, normals4_many, box_muller_batch

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

    !> philox4x32_10 through the int32 rounds of the batch kernel (about a third of the
    !> instructions): the block of one counter for rng_block and the streams.
    pure function philox_block(ctr, key) result(c)
        integer(i8), intent(in) :: ctr(4), key(2)
        integer(i8) :: c(4)
        integer(i4) :: k0(10), k1(10), x0, x1, x2, x3
        call round_keys(key, k0, k1)
        x0 = pattern32(ctr(1)); x1 = pattern32(ctr(2)); x2 = pattern32(ctr(3)); x3 = pattern32(ctr(4))
        call philox_rounds(k0, k1, x0, x1, x2, x3)
        c = iand(int([x0, x1, x2, x3], i8), mask32)
    end function philox_block

    !> Philox4x32-10 on n counters at once (c(:, 1..4) in place; the same key): the same words as
    !> philox4x32_10 counter by counter, through the vectorised rounds of philox_rounds.
    pure subroutine rng_blocks(n, c, key)
        integer, intent(in) :: n
        integer(i8), intent(inout) :: c(n, 4)
        integer(i8), intent(in) :: key(2)
        integer(i4) :: k0(10), k1(10), x0, x1, x2, x3
        integer :: i
        call round_keys(key, k0, k1)
        do i = 1, n
            x0 = pattern32(c(i, 1)); x1 = pattern32(c(i, 2)); x2 = pattern32(c(i, 3)); x3 = pattern32(c(i, 4))
            call philox_rounds(k0, k1, x0, x1, x2, x3)
            c(i, 1) = iand(int(x0, i8), mask32); c(i, 2) = iand(int(x1, i8), mask32)
            c(i, 3) = iand(int(x2, i8), mask32); c(i, 4) = iand(int(x3, i8), mask32)
        end do
    end subroutine rng_blocks

    !> The ten round keys (k0, k1) of key, as 32-bit patterns.
    pure subroutine round_keys(key, k0, k1)
        integer(i8), intent(in) :: key(2)
        integer(i4), intent(out) :: k0(10), k1(10)
        integer(i8) :: a, b
        integer :: r
        a = key(1); b = key(2)
        do r = 1, 10
            k0(r) = pattern32(a)
            k1(r) = pattern32(b)
            a = iand(a + philox_w0, mask32); b = iand(b + philox_w1, mask32)
        end do
    end subroutine round_keys

    !> The int32 bit pattern of a word w in [0, 2^32).
    elemental integer(i4) function pattern32(w) result(p)
        integer(i8), intent(in) :: w
        p = int(w - merge(4294967296_i8, 0_i8, w > 2147483647_i8), i4)
    end function pattern32

    !> The ten Philox rounds on one counter held as four 32-bit patterns (x0..x3 in place). Written
    !> for the vectoriser (inlined into loops over counters): the zero-extended word times the
    !> multiplier is one unsigned 32 x 32 -> 64-bit product (vpmuludq); the product wraps past
    !> 2^63 and the words are taken modulo 2^32, so this file is compiled with -fwrapv.
    pure subroutine philox_rounds(k0, k1, x0, x1, x2, x3)
        integer(i4), intent(in) :: k0(10), k1(10)
        integer(i4), intent(inout) :: x0, x1, x2, x3
        integer(i8) :: p0, p1
        integer :: r
!GCC$ unroll 10
        do r = 1, 10
            p0 = iand(int(x0, i8), mask32)*philox_m0
            p1 = iand(int(x2, i8), mask32)*philox_m1
            x0 = ieor(ieor(int(ishft(p1, -32), i4), x1), k0(r))
            x2 = ieor(ieor(int(ishft(p0, -32), i4), x3), k1(r))
            x1 = int(p1, i4); x3 = int(p0, i4)
        end do
    end subroutine philox_rounds

    !> normals4 for n ids at once (the same numbers as normals4 id by id): z(i, 1..4). Two
    !> vectorised loops over the batch: the Philox blocks of (seed, stream, id, event, 0), then two
    !> Box-Muller pairs per block (box_muller_batch). Any n gives the same numbers for an id (the
    !> vector and the remainder code agree bitwise, unit-tested).
    pure subroutine normals4_many(n, seed, stream, ids, event, z)
        integer, intent(in) :: n, stream
        integer(i8), intent(in) :: seed, ids(n), event
        real(dp), intent(out) :: z(n, 4)
        integer(i4) :: k0(10), k1(10), ev_lo, ev_hi, w(n, 4)
        integer :: i
        call round_keys(rng_key(seed, stream), k0, k1)
        ev_lo = pattern32(ishft(iand(event, mask16), 16))
        ev_hi = pattern32(iand(ishft(event, -16), mask32))
        ! the counter words first (a loop of their own: the next one holds no 64-bit integer loads)
        do i = 1, n
            w(i, 1) = 0
            w(i, 2) = pattern32(iand(ids(i), mask32))
            w(i, 3) = ior(pattern32(iand(ishft(ids(i), -32), mask16)), ev_lo)
            w(i, 4) = ev_hi
        end do
        do i = 1, n
            call philox_rounds(k0, k1, w(i, 1), w(i, 2), w(i, 3), w(i, 4))
        end do
        call box_muller_batch(n, w(:, 1), w(:, 2), z(:, 1), z(:, 2))
        call box_muller_batch(n, w(:, 3), w(:, 4), z(:, 3), z(:, 4))
    end subroutine normals4_many

    !> Box-Muller on n pairs of 32-bit words (patterns), one branch-free loop that vectorises:
    !>   r = sqrt(-2 ln u), u = (wr + 1/2) 2^-32, with ln u = e ln 2 + ln m (u = m 2^e, m in
    !>   [sqrt(1/2), sqrt(2))), ln m = 2 atanh(s), s = (m - 1)/(m + 1), |s| < 0.172, by its series
    !>   to s^21 (truncation below 1e-18);
    !>   the angle 2 pi (wa + 1/2) 2^-32 = k pi/2 + t, split exactly into the nearest quarter turn k
    !>   and t in [-pi/4, pi/4]; sin t and cos t by their Taylor polynomials (to t^15 and t^16,
    !>   truncation below 5e-17); cos and sin of the angle are then +-cos t or +-sin t.
    !> The same numbers as box_muller on the same uniforms to a few ulp, without the library's
    !> scalar log, sin and cos.
    pure subroutine box_muller_batch(n, wr, wa, z1, z2)
        integer, intent(in) :: n
        integer(i4), intent(in) :: wr(n), wa(n)
        real(dp), intent(out) :: z1(n), z2(n)
        integer(i8), parameter :: mant_mask = 4503599627370495_i8, one_bits = 4607182418800017408_i8
        real(dp), parameter :: ln2_hi = 6.93147180369123816490e-01_dp, ln2_lo = 1.90821492927058770002e-10_dp
        integer(i8) :: b
        integer(i4) :: q, k
        real(dp) :: u, m, e, s, s2, y, r, t, t2, sn, cs, cc, ss
        integer :: i
        do i = 1, n
            ! r = sqrt(-2 ln u)
            u = (real(wr(i), dp) + merge(4294967296.5_dp, 0.5_dp, wr(i) < 0))*inv_2_32
            b = transfer(u, b)
            e = real(int(ishft(b, -52), i4) - 1023_i4, dp)
            m = transfer(ior(iand(b, mant_mask), one_bits), m)
            e = e + merge(1.0_dp, 0.0_dp, m > sqrt_2)
            m = merge(0.5_dp*m, m, m > sqrt_2)
            s = (m - 1)/(m + 1)
            s2 = s*s
            y = 1.0_dp/21
            y = y*s2 + 1.0_dp/19
            y = y*s2 + 1.0_dp/17
            y = y*s2 + 1.0_dp/15
            y = y*s2 + 1.0_dp/13
            y = y*s2 + 1.0_dp/11
            y = y*s2 + 1.0_dp/9
            y = y*s2 + 1.0_dp/7
            y = y*s2 + 1.0_dp/5
            y = y*s2 + 1.0_dp/3
            y = (y*s2)*s + s
            r = sqrt(-2*(e*ln2_hi + (2*y + e*ln2_lo)))
            ! the angle: q = wa + 2^29, k = q div 2^30 mod 4, t = (q mod 2^30 - 2^29 + 1/2) (pi/2) 2^-30
            q = wa(i) + 536870912_i4
            k = iand(ishft(q, -30), 3_i4)
            t = (real(iand(q, 1073741823_i4), dp) - 536870911.5_dp)*(two_pi/4294967296.0_dp)
            t2 = t*t
            sn = -1.0_dp/1307674368000.0_dp
            sn = sn*t2 + 1.0_dp/6227020800.0_dp
            sn = sn*t2 - 1.0_dp/39916800.0_dp
            sn = sn*t2 + 1.0_dp/362880.0_dp
            sn = sn*t2 - 1.0_dp/5040.0_dp
            sn = sn*t2 + 1.0_dp/120.0_dp
            sn = sn*t2 - 1.0_dp/6.0_dp
            sn = (sn*t2)*t + t
            cs = 1.0_dp/20922789888000.0_dp
            cs = cs*t2 - 1.0_dp/87178291200.0_dp
            cs = cs*t2 + 1.0_dp/479001600.0_dp
            cs = cs*t2 - 1.0_dp/3628800.0_dp
            cs = cs*t2 + 1.0_dp/40320.0_dp
            cs = cs*t2 - 1.0_dp/720.0_dp
            cs = cs*t2 + 1.0_dp/24.0_dp
            cs = cs*t2 - 0.5_dp
            cs = cs*t2 + 1
            cc = merge(sn, cs, iand(k, 1_i4) == 1)
            ss = merge(cs, sn, iand(k, 1_i4) == 1)
            z1(i) = r*merge(-cc, cc, iand(k + 1_i4, 2_i4) /= 0)
            z2(i) = r*merge(-ss, ss, iand(k, 2_i4) /= 0)
        end do
    end subroutine box_muller_batch

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

    !> Four standard normals from one block (32-bit uniforms: tails cut at |z| ~ 6.7, a
    !> probability of 2e-11): normals4_many for one id, bitwise the batch kernel's numbers.
    pure subroutine normals4(seed, stream, id, event, z)
        integer(i8), intent(in) :: seed, id, event
        integer, intent(in) :: stream
        real(dp), intent(out) :: z(4)
        real(dp) :: zz(1, 4)
        call normals4_many(1, seed, stream, [id], event, zz)
        z = zz(1, :)
    end subroutine normals4

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
