!> The energy-stepping event solver: the first time s > 0 at which f(s) = V(x + s v) leaves the
!> current terrace [lower, upper], searched inside a window (0, s_max].
!>
!> A ray evaluation returns f, f' and f'' at one s (one pass over the pairs, one global sum).
!> The search steps from s0 to the root of the Taylor quadratic f0 + f0' s + f0'' s^2/2 = level
!> (capped by a trust length), evaluates there, and decides whether the interval [s0, s1] can hold
!> a crossing: the cubic Hermite interpolant p through (f, f') at both ends, widened by an error
!> band e(s) = M (s - s0)^2 (s1 - s)^2 whose size M comes from the mismatch between p'' and the
!> measured f'' at the ends (the Hermite remainder f''''/24 (s-s0)^2 (s-s1)^2), is sampled for a
!> violation of either level. A clear interval is accepted, a violation is probed (evaluated at
!> the worst point) until it is either a real crossing (bracket) or clear. A bracket is refined
!> by Halley steps from its inside end with a Hermite/bisection fallback, each candidate interval
!> re-checked, so that a crossing that goes out and back inside one step is not stepped over.
!> When the predicted error of the next Halley step is below the tolerance the root is returned
!> unevaluated: the caller's force pass at the kick point verifies it.
module terrace_event_solver
    use terrace_kinds, only: dp
    implicit none
    private

    !> A ray s -> f(s) along which the solver searches (the engine, or an analytic test function).
    type, abstract, public :: ray_t
        integer :: evals = 0
    contains
        procedure(ray_eval_i), deferred :: eval_ray
        procedure :: eval => ray_eval_counted
    end type ray_t

    abstract interface
        subroutine ray_eval_i(self, s, fdc)
            import :: ray_t, dp
            class(ray_t), intent(inout) :: self
            real(dp), intent(in) :: s
            real(dp), intent(out) :: fdc(3)     !< f, f', f'' at s
        end subroutine ray_eval_i
    end interface

    integer, parameter, public :: level_none = 0, level_upper = 1, level_lower = -1

    type, public :: crossing_t
        logical :: found = .false.
        real(dp) :: s = 0                  !< crossing time (found), or s_max (not found)
        integer :: level = level_none      !< which edge is crossed
        logical :: evaluated = .false.     !< fdc holds f, f', f'' at s
        real(dp) :: fdc(3) = 0
        real(dp) :: c_near = 0             !< f'' at the evaluated point nearest to s (a guess for later)
    end type crossing_t

    type, public :: event_solver_t
        real(dp) :: tol = 1.0e-9_dp        !< absolute tolerance on |f(s) - level| (root_tolerance * h)
        real(dp) :: band_safety = 16       !< widening of the Hermite error band (4 until 2026-11-27: scripts/bench/solver_random_rays.sh stepped over twice as many excursions)
        integer :: samples = 16            !< points at which the band is checked per interval
        integer :: max_evals = 400
    contains
        procedure :: first_crossing => solver_first_crossing
    end type event_solver_t

    public :: taylor_step, hermite_value

contains

    subroutine ray_eval_counted(self, s, fdc)
        class(ray_t), intent(inout) :: self
        real(dp), intent(in) :: s
        real(dp), intent(out) :: fdc(3)
        self%evals = self%evals + 1
        call self%eval_ray(s, fdc)
    end subroutine ray_eval_counted

    !> Smallest root delta > 0 of f + d delta + c delta^2 / 2 = level (huge if none), computed
    !> without cancellation. A state exactly on the level does not count delta = 0.
    pure real(dp) function taylor_step(f, d, c, level) result(step)
        real(dp), intent(in) :: f, d, c, level
        real(dp) :: a2, g, disc, q, r1, r2
        step = huge(1.0_dp)
        g = f - level
        a2 = 0.5_dp*c
        if (abs(a2) <= tiny(1.0_dp)) then
            if (d /= 0) then
                r1 = -g/d
                if (r1 > 0) step = r1
            end if
            return
        end if
        disc = d*d - 4*a2*g
        if (disc < 0) return
        q = -0.5_dp*(d + sign(sqrt(disc), d))
        if (q /= 0) then
            r1 = q/a2
            r2 = g/q
        else
            r1 = 0; r2 = 0
        end if
        if (r1 > 0) step = min(step, r1)
        if (r2 > 0) step = min(step, r2)
    end function taylor_step

    !> Cubic Hermite interpolant through (s0, f0, d0) and (s1, f1, d1): value at s.
    pure real(dp) function hermite_value(s0, f0, d0, s1, f1, d1, s) result(p)
        real(dp), intent(in) :: s0, f0, d0, s1, f1, d1, s
        real(dp) :: h, t, h00, h10, h01, h11
        h = s1 - s0
        t = (s - s0)/h
        h00 = (1 + 2*t)*(1 - t)**2
        h10 = t*(1 - t)**2
        h01 = t*t*(3 - 2*t)
        h11 = t*t*(t - 1)
        p = h00*f0 + h10*h*d0 + h01*f1 + h11*h*d1
    end function hermite_value

    !> Classify [s0, s1]: 0 clear, 1 crossing certain (f1 beyond a level), 2 unsure (probe at sp).
    !> The band p +- e is sampled at `samples` interior points. Two shortcuts leave the answer
    !> unchanged: with f1 beyond a level the answer is 1 or 2 from the second scan alone (the first
    !> one's worst point is not used), and a scan is skipped when a bound on the whole interval shows
    !> that no sample can fail its test. The bound: p +- e are quartics in t = (s - s0)/h, each between
    !> the smallest and the largest of its Bernstein coefficients: those of the cubic raised to degree
    !> 4 (from f0, f0 + h f0'/3, f1 - h f1'/3, f1), the band's (0, 0, +-E/6, 0, 0), E = band h^4, since
    !> t^2 (1 - t)^2 = B(2,4)/6. A margin of 32 eps of the values' size covers the samples' round-off.
    subroutine classify(self, s0, p0, s1, p1, lower, upper, status, sp)
        class(event_solver_t), intent(in) :: self
        real(dp), intent(in) :: s0, p0(3), s1, p1(3), lower, upper
        integer, intent(out) :: status
        real(dp), intent(out) :: sp
        real(dp) :: h, c0h, c1h, m, band, s, p, e, worst, viol, b1, b2, c1, c2, c3, e6, pmin, pmax, margin
        integer :: k
        h = s1 - s0
        sp = 0.5_dp*(s0 + s1)
        ! second derivatives of the Hermite cubic at its ends
        c0h = (6*(p1(1) - p0(1))/h - 4*p0(2) - 2*p1(2))/h
        c1h = (-6*(p1(1) - p0(1))/h + 2*p0(2) + 4*p1(2))/h
        m = max(abs(c0h - p0(3)), abs(c1h - p1(3)))
        ! an interval so short that its band overflows (h ~ 1e-100 at a kink of the potential, where
        ! the probes of scan_interval close in on one end): decided by the end value, as scan_interval
        ! decides an interval too short for f to move by the tolerance (the band, infinite, would
        ! only turn the tests below into NaN comparisons)
        if (.not. (2*h*h > 0) .or. m > (huge(1.0_dp)/self%band_safety)*(2*h*h)) then
            status = merge(1, 0, beyond_tol(p1(1), lower, upper, self%tol))
            return
        end if
        band = self%band_safety*m/(2*h*h)
        worst = 0
        status = 0
        ! the cubic does not reproduce the measured curvature at the ends (the interval is not
        ! resolved, e.g. a narrow bump inside) and the band would matter: probe the middle
        if (m > 0.5_dp*max(abs(p0(3)), abs(p1(3)), abs(c0h), abs(c1h)) .and. band*h**4/16 > self%tol) then
            status = 2; sp = 0.5_dp*(s0 + s1)
            if (.not. beyond_tol(p1(1), lower, upper, self%tol)) return
        end if
        ! the ranges of p - e and p + e (Bernstein coefficients), with the round-off margin
        b1 = p0(1) + h*p0(2)/3
        b2 = p1(1) - h*p1(2)/3
        c1 = 0.25_dp*(p0(1) + 3*b1); c2 = 0.5_dp*(b1 + b2); c3 = 0.25_dp*(3*b2 + p1(1))
        e6 = band*h**4/6
        pmin = min(p0(1), c1, c2 - e6, c3, p1(1)); pmax = max(p0(1), c1, c2 + e6, c3, p1(1))
        margin = 32*epsilon(1.0_dp)*(abs(p0(1)) + abs(p1(1)) + abs(h*p0(2)) + abs(h*p1(2)) + abs(lower) + &
                                     abs(upper) + e6 + self%tol)
        if (beyond_tol(p1(1), lower, upper, self%tol)) then
            ! a crossing is certain; unsure only if the other level may be crossed first
            status = 1
            if (p1(1) > upper) then
                if (pmin - margin >= lower) return
            else
                if (pmax + margin <= upper) return
            end if
            do k = 1, self%samples
                s = s0 + h*k/real(self%samples + 1, dp)
                p = hermite_value(s0, p0(1), p0(2), s1, p1(1), p1(2), s)
                e = band*(s - s0)**2*(s1 - s)**2
                if ((p1(1) > upper .and. p - e < lower) .or. (p1(1) < lower .and. p + e > upper)) then
                    status = 2; sp = s
                    exit
                end if
            end do
            return
        end if
        ! an excursion by less than the tolerance is within the accuracy contract: not a crossing
        if (pmax + margin <= upper + self%tol .and. pmin - margin >= lower - self%tol) return
        do k = 1, self%samples
            s = s0 + h*k/real(self%samples + 1, dp)
            p = hermite_value(s0, p0(1), p0(2), s1, p1(1), p1(2), s)
            e = band*(s - s0)**2*(s1 - s)**2
            viol = max(p + e - upper, lower - (p - e)) - self%tol
            if (viol > worst) then
                worst = viol; sp = s
                status = 2
            end if
        end do
    end subroutine classify

    !> f beyond a level by more than tol: the exact complement of |f - level| <= tol near a level (the
    !> differences are exact there), which the acceptance of a root at an evaluated point tests. upper +
    !> tol would round (at |V| ~ 2e5 an ulp of V is 1 % of a tol of 64 eps |V|) and leave a value in
    !> neither class: not beyond, not accepted, and the search went on past it to bisect a bracket whose
    !> inside end is already beyond down to round-off (~40 ray evaluations).
    pure logical function beyond_tol(f, lower, upper, tol)
        real(dp), intent(in) :: f, lower, upper, tol
        beyond_tol = f - upper > tol .or. lower - f > tol
    end function beyond_tol

    pure logical function beyond(f, lower, upper)
        real(dp), intent(in) :: f, lower, upper
        beyond = f > upper .or. f < lower
    end function beyond

    !> Verify [s0, s1] (f(s0) inside): status 0 if no crossing can hide in it, else status 1 and
    !> a bracket [sa, sb] with f(sa) inside and f(sb) beyond a level, the earliest one found.
    !> Unsure sub-intervals are probed, left first (a small stack of right ends).
    subroutine scan_interval(self, ray, s0, p0, s1, p1, lower, upper, status, sa, pa, sb, pb)
        class(event_solver_t), intent(in) :: self
        class(ray_t), intent(inout) :: ray
        real(dp), intent(in) :: s0, p0(3), s1, p1(3), lower, upper
        integer, intent(out) :: status
        real(dp), intent(out) :: sa, pa(3), sb, pb(3)
        integer, parameter :: depth = 64
        real(dp) :: st_s(depth), st_p(3, depth), sp, pp(3)
        integer :: top, cls, probes
        sa = s0; pa = p0
        top = 1; st_s(1) = s1; st_p(:, 1) = p1
        probes = 0
        do while (top > 0)
            call classify(self, sa, pa, st_s(top), st_p(:, top), lower, upper, cls, sp)
            ! an interval too short for f to move by the tolerance, a full stack or too many probes:
            ! decide by the end value
            if (cls == 2 .and. (top == depth .or. probes > self%max_evals .or. &
                                (st_s(top) - sa)*max(abs(pa(2)), abs(st_p(2, top))) <= self%tol .or. &
                                st_s(top) - sa <= 1.0e-13_dp*max(abs(sa), abs(st_s(top))))) then
                cls = merge(1, 0, beyond_tol(st_p(1, top), lower, upper, self%tol))
            end if
            select case (cls)
            case (0)
                sa = st_s(top); pa = st_p(:, top)
                top = top - 1
            case (1)
                status = 1
                sb = st_s(top); pb = st_p(:, top)
                return
            case default
                call ray%eval(sp, pp)
                probes = probes + 1
                top = top + 1
                st_s(top) = sp; st_p(:, top) = pp
            end select
        end do
        status = 0
        sb = s1; pb = p1
    end subroutine scan_interval

    !> First crossing of lower or upper by f(s), 0 < s <= s_max. p0 = (f, f', f'') at s = 0 when
    !> have_c0, else only (f, f') are known: then f'' is evaluated first, unless c0_guess is given
    !> (the curvature just before a velocity jump): it only aims the first step, and the first
    !> interval is checked with the curvature of its cubic at s = 0 instead of a measured one.
    !> trust caps every step.
    subroutine solver_first_crossing(self, ray, lower, upper, s_max, p0_in, have_c0, trust_in, res, c0_guess)
        class(event_solver_t), intent(in) :: self
        class(ray_t), intent(inout) :: ray
        real(dp), intent(in) :: lower, upper, s_max, p0_in(3), trust_in
        logical, intent(in) :: have_c0
        type(crossing_t), intent(out) :: res
        real(dp), intent(in), optional :: c0_guess
        real(dp) :: s0, p0(3), s1, p1(3), sa, pa(3), sb, pb(3), step, trust, su, sl, h
        integer :: status
        logical :: c0_unknown
        s0 = 0
        p0 = p0_in
        c0_unknown = .false.
        if (.not. have_c0) then
            if (present(c0_guess)) then
                p0(3) = c0_guess
                c0_unknown = .true.
            else
                call ray%eval(0.0_dp, p0)
                p0(1:2) = p0_in(1:2)
            end if
        end if
        trust = max(trust_in, tiny(1.0_dp))

        do
            step = min(taylor_step(p0(1), p0(2), p0(3), upper), taylor_step(p0(1), p0(2), p0(3), lower))
            step = min(step, trust, s_max - s0)
            s1 = min(s0 + step, s_max)
            if (.not. (s1 > s0)) exit
            call ray%eval(s1, p1)
            if (c0_unknown) then
                h = s1 - s0
                p0(3) = (6*(p1(1) - p0(1))/h - 4*p0(2) - 2*p1(2))/h     ! the cubic's curvature at s0
                c0_unknown = .false.
            end if
            call scan_interval(self, ray, s0, p0, s1, p1, lower, upper, status, sa, pa, sb, pb)
            if (status == 1) then
                call refine(self, ray, sa, pa, sb, pb, lower, upper, res)
                return
            end if
            ! clear up to s1: a root within tolerance at s1 itself, moving outwards?
            ! (it must really go across: beyond by half the tolerance, or the local quadratic gets
            ! there; a ray that only touches a level, as a chord tangent to a level set does, is not
            ! a crossing. Measured from the level, f - level, which is exact: upper + tol/2 would
            ! round, and a value on it counted as neither beyond nor getting there)
            if (abs(p1(1) - upper) <= self%tol .and. p1(2) > 0 .and. (p1(1) - upper > 0.5_dp*self%tol .or. &
                taylor_step(p1(1) - upper, p1(2), p1(3), 0.5_dp*self%tol) < huge(1.0_dp))) then
                res = crossing_t(.true., s1, level_upper, .true., p1, p1(3)); return
            end if
            if (abs(p1(1) - lower) <= self%tol .and. p1(2) < 0 .and. (lower - p1(1) > 0.5_dp*self%tol .or. &
                taylor_step(p1(1) - lower, p1(2), p1(3), -0.5_dp*self%tol) < huge(1.0_dp))) then
                res = crossing_t(.true., s1, level_lower, .true., p1, p1(3)); return
            end if
            ! the next Taylor root is so close that its predicted error (f''' from the two ends)
            ! is below the tolerance: return it unevaluated, the force pass at the kick verifies it
            ! (only a real crossing: the quadratic must also get beyond the level by tol/2)
            su = huge(1.0_dp); sl = huge(1.0_dp)
            if (taylor_step(p1(1) - upper, p1(2), p1(3), 0.5_dp*self%tol) < huge(1.0_dp)) &
                su = taylor_step(p1(1), p1(2), p1(3), upper)
            if (taylor_step(p1(1) - lower, p1(2), p1(3), -0.5_dp*self%tol) < huge(1.0_dp)) &
                sl = taylor_step(p1(1), p1(2), p1(3), lower)
            step = min(su, sl)
            if (step < 0.25_dp*(s1 - s0) .and. s1 + step <= s_max) then
                if (abs(p1(3) - p0(3))/(s1 - s0)*step**3/6 < 0.1_dp*self%tol) then
                    res = crossing_t(.true., s1 + step, merge(level_upper, level_lower, su <= sl), .false., &
                                     [0.0_dp, 0.0_dp, 0.0_dp], p1(3))
                    return
                end if
            end if
            s0 = s1; p0 = p1     ! trust stays a cap on every step
            if (s0 >= s_max) exit
        end do
        res%found = .false.; res%s = s0; res%evaluated = .true.; res%fdc = p0; res%c_near = p0(3)
    end subroutine solver_first_crossing

    !> Root of f = level in the bracket [sa, sb] (f(sa) inside, f(sb) beyond): Halley steps from
    !> the end nearer the level, Hermite bisection as fallback, every move of the inside end
    !> re-verified so that the root found is the first one.
    subroutine refine(self, ray, sa_in, pa_in, sb_in, pb_in, lower, upper, res)
        class(event_solver_t), intent(in) :: self
        class(ray_t), intent(inout) :: ray
        real(dp), intent(in) :: sa_in, pa_in(3), sb_in, pb_in(3), lower, upper
        type(crossing_t), intent(out) :: res
        real(dp) :: sa, pa(3), sb, pb(3), sn, pn(3), lv, third, ua, ub, err, xa, xb, a2(3), b2(3), width, margin, &
                    last_width
        integer :: it, lvl, status
        logical :: slow, from_b
        sa = sa_in; pa = pa_in; sb = sb_in; pb = pb_in
        last_width = huge(1.0_dp)
        slow = .false.
        do it = 1, self%max_evals
            if (sb - sa <= 4*epsilon(1.0_dp)*max(abs(sa), abs(sb))) exit   ! bracket at round-off
            slow = (sb - sa) > 0.7_dp*last_width
            last_width = sb - sa
            lv = merge(upper, lower, pb(1) > upper)
            lvl = merge(level_upper, level_lower, pb(1) > upper)
            third = abs(pb(3) - pa(3))/(sb - sa)
            ua = taylor_step(pa(1), pa(2), pa(3), lv)              ! forward from sa
            ub = taylor_step(pb(1), -pb(2), pb(3), lv)             ! backward from sb
            width = sb - sa
            margin = 1.0e-6_dp*width
            sn = -huge(1.0_dp); err = huge(1.0_dp); from_b = .false.
            if (.not. slow) then
                if (ua > margin .and. ua < width - margin) then
                    sn = sa + ua; err = third*ua**3/6
                end if
                if (ub > margin .and. ub < width - margin) then      ! (nested: ub may be huge)
                    if (third*ub**3/6 < err) then
                        sn = sb - ub; err = third*ub**3/6; from_b = .true.
                    end if
                end if
                ! A root predicted back from the beyond end says nothing of [sa, sb - ub]: before
                ! it is returned unevaluated, that interval, with the values predicted at the root,
                ! must be clear of any other crossing (the check scan_interval makes after an
                ! evaluation; classify of the bracket itself, certain of the crossing at sb, does not
                ! look for an excursion of the same level before it). Within the margin of sb (sb
                ! overshot the level by little: a nearly harmonic ray, e.g. a crystal near its
                ! lattice, whose Taylor step lands within ~1e-7 of its length of the root) the root
                ! is too close to sb to shrink the bracket as a Halley step: returned when clear,
                ! else the bracket is bisected. (Bisecting until ub exceeded the margin cost ~4 ray
                ! evaluations per event on the 32,000-atom fcc start.)
                if (sn < sa .and. ub > 0 .and. ub <= margin) then
                    sn = sb - ub; err = third*ub**3/6; from_b = .true.
                end if
                if (from_b .and. err < 0.1_dp*self%tol) then
                    if (sn > sa .and. sn < sb) then
                        pn = [lv, pb(2) - pb(3)*ub, pb(3) - (pb(3) - pa(3))/width*ub]
                        call classify(self, sa, pa, sn, pn, lower, upper, status, xa)
                        if (status == 0) then
                            res = crossing_t(.true., sn, lvl, .false., [0.0_dp, 0.0_dp, 0.0_dp], pb(3)); return
                        end if
                    end if
                    err = huge(1.0_dp)                      ! not clear: evaluate there, or bisect
                    if (ub <= margin) sn = -huge(1.0_dp)
                end if
                if (sn < sa) then
                    sn = hermite_root(sa, pa, sb, pb, lv)
                    if (.not. (sn > sa + margin .and. sn < sb - margin)) sn = sa + 0.5_dp*width
                end if
            else
                sn = sa + 0.5_dp*width        ! the bracket stopped shrinking: bisect
            end if
            if (err < 0.1_dp*self%tol) then   ! a root forward from the inside end
                res = crossing_t(.true., sn, lvl, .false., [0.0_dp, 0.0_dp, 0.0_dp], &
                                 merge(pa(3), pb(3), sn - sa < sb - sn)); return
            end if
            call ray%eval(sn, pn)
            if (abs(pn(1) - lv) <= self%tol .or. beyond(pn(1), lower, upper)) then
                call scan_interval(self, ray, sa, pa, sn, pn, lower, upper, status, xa, a2, xb, b2)
                if (status == 1 .and. xb < sn) then
                    sa = xa; pa = a2; sb = xb; pb = b2        ! an earlier crossing
                    cycle
                end if
                if (abs(pn(1) - lv) <= self%tol) then
                    res = crossing_t(.true., sn, lvl, .true., pn, pn(3)); return
                end if
                sa = xa; pa = a2; sb = sn; pb = pn
            else
                call scan_interval(self, ray, sa, pa, sn, pn, lower, upper, status, xa, a2, xb, b2)
                if (status == 1) then
                    sa = xa; pa = a2; sb = xb; pb = b2
                else
                    sa = sn; pa = pn
                end if
            end if
        end do
        res = crossing_t(.true., sa, merge(level_upper, level_lower, pb(1) > upper), .true., pa, pa(3))
    end subroutine refine

    !> Root of the Hermite cubic = lv in (sa, sb) by bisection (sa inside, sb beyond).
    pure real(dp) function hermite_root(sa, pa, sb, pb, lv) result(s)
        real(dp), intent(in) :: sa, pa(3), sb, pb(3), lv
        real(dp) :: lo, hi, mid, gl
        integer :: k
        lo = sa; hi = sb
        gl = pa(1) - lv
        do k = 1, 60
            mid = 0.5_dp*(lo + hi)
            if ((hermite_value(sa, pa(1), pa(2), sb, pb(1), pb(2), mid) - lv)*gl > 0) then
                lo = mid
            else
                hi = mid
            end if
        end do
        s = 0.5_dp*(lo + hi)
        if (.not. (s > sa .and. s < sb)) s = 0.5_dp*(sa + sb)
    end function hermite_root

end module terrace_event_solver
