!> Stepped pair potentials (hard spheres, square wells, any piecewise-constant pair energy) and
!> the two closed forms event-driven dynamics needs from them: when a pair in straight-line motion
!> next crosses one of its radii, and what a crossing does to the two velocities.
!>
!> A type pair has radii r(1) > r(2) > ... > r(nr) and a constant energy in each region between
!> them: region s (0 <= s <= nr) is r(s+1) < |r_ij| < r(s) (r(0) = infinity, r(nr+1) = 0), with
!> energy u(s), u(0) = 0. The innermost radius is a hard core (u(nr) is infinite): every crossing
!> of it is a reflection. Crossing radius k inward takes a pair from region k-1 to k, outward from
!> k to k-1; the energy step is dU = u(new) - u(old).
!>
!> Collision rule: the impulse acts along the unit vector e = r_ij/|r_ij| at the crossing. With
!> the reduced mass mu and the normal relative velocity v_n = (v_i - v_j).e, the pair crosses when
!> mu v_n^2/2 > dU, with v_n' = sign(v_n) sqrt(v_n^2 - 2 dU/mu); otherwise it reflects, v_n' = -v_n.
!> v_i += mu (v_n' - v_n)/m_i e, v_j -= mu (v_n' - v_n)/m_j e: momentum and angular momentum are
!> unchanged (equal and opposite impulses along the line of centres) and the kinetic energy changes
!> by exactly -dU (0 for a reflection), up to round-off.
module terrace_stepped_pair
    use terrace_kinds, only: dp
    implicit none
    private

    integer, parameter, public :: max_radii = 4
    real(dp), parameter, public :: no_event = huge(1.0_dp)

    !> Per type pair (ti, tj), symmetric.
    type, public :: stepped_table_t
        integer :: ntypes = 0
        integer, allocatable :: nr(:, :)          !< radii of the pair
        real(dp), allocatable :: r(:, :, :)       !< (k, ti, tj) radii, descending
        real(dp), allocatable :: r2(:, :, :)      !< their squares
        real(dp), allocatable :: u(:, :, :)       !< (0:max_radii, ti, tj) region energies, u(0) = 0
        real(dp) :: rmax = 0                      !< the largest radius of any pair
        logical :: has_steps = .false.            !< some pair has a finite step (a well or a shoulder)
    contains
        procedure :: init => table_init
        procedure :: set_pair => table_set_pair
        procedure :: region_of => table_region_of
    end type stepped_table_t

    public :: inward_time, outward_time, collide

contains

    subroutine table_init(self, ntypes)
        class(stepped_table_t), intent(inout) :: self
        integer, intent(in) :: ntypes
        self%ntypes = ntypes
        if (allocated(self%nr)) deallocate (self%nr, self%r, self%r2, self%u)
        allocate (self%nr(ntypes, ntypes), self%r(max_radii, ntypes, ntypes), self%r2(max_radii, ntypes, ntypes), &
                  self%u(0:max_radii, ntypes, ntypes))
        self%nr = 0; self%r = 0; self%r2 = 0; self%u = 0
        self%rmax = 0; self%has_steps = .false.
    end subroutine table_init

    !> Radii (descending, the last one the hard core) and the energies of the regions inside each
    !> radius but the core: energies(k) is the energy between radius k and radius k+1.
    subroutine table_set_pair(self, ti, tj, radii, energies)
        class(stepped_table_t), intent(inout) :: self
        integer, intent(in) :: ti, tj
        real(dp), intent(in) :: radii(:), energies(:)
        integer :: n
        n = size(radii)
        self%nr(ti, tj) = n
        self%r(1:n, ti, tj) = radii
        self%r2(1:n, ti, tj) = radii**2
        self%u(0, ti, tj) = 0
        self%u(1:n - 1, ti, tj) = energies(1:n - 1)
        self%u(n, ti, tj) = huge(1.0_dp)
        self%nr(tj, ti) = self%nr(ti, tj)
        self%r(:, tj, ti) = self%r(:, ti, tj); self%r2(:, tj, ti) = self%r2(:, ti, tj)
        self%u(:, tj, ti) = self%u(:, ti, tj)
        self%rmax = max(self%rmax, radii(1))
        if (n > 1) self%has_steps = .true.
    end subroutine table_set_pair

    !> The region of a pair at squared distance rsq (number of radii it lies inside).
    pure integer function table_region_of(self, ti, tj, rsq) result(s)
        class(stepped_table_t), intent(in) :: self
        integer, intent(in) :: ti, tj
        real(dp), intent(in) :: rsq
        integer :: k
        s = 0
        do k = 1, self%nr(ti, tj)
            if (rsq < self%r2(k, ti, tj)) s = k
        end do
    end function table_region_of

    !> Time until |dx + t dv| falls to radius sqrt(rk2) from outside (the earlier root of
    !> |dx + t dv|^2 = rk2), no_event when the pair does not approach or misses. b = dx.dv,
    !> c = |dx|^2 - rk2; the root is written as c / (-b + sqrt(b^2 - v^2 c)), which has no
    !> cancellation for b < 0. A pair already inside by round-off (c < 0) while approaching meets
    !> the radius now (0).
    pure real(dp) function inward_time(dx, dv, rk2) result(t)
        real(dp), intent(in) :: dx(3), dv(3), rk2
        real(dp) :: b, c, vv, disc
        t = no_event
        b = dx(1)*dv(1) + dx(2)*dv(2) + dx(3)*dv(3)
        if (.not. (b < 0)) return
        vv = dv(1)**2 + dv(2)**2 + dv(3)**2
        c = dx(1)**2 + dx(2)**2 + dx(3)**2 - rk2
        if (c <= 0) then
            t = 0
            return
        end if
        disc = b*b - vv*c
        if (disc < 0) return
        t = c/(-b + sqrt(disc))
    end function inward_time

    !> Time until |dx + t dv| rises to radius sqrt(rk2) from inside (the later root). For b < 0
    !> it is (-b + sqrt(D))/v^2, for b >= 0 -c/(b + sqrt(D)) (c <= 0 inside): no cancellation
    !> either way. A pair already outside by round-off while receding meets it now (0).
    pure real(dp) function outward_time(dx, dv, rk2) result(t)
        real(dp), intent(in) :: dx(3), dv(3), rk2
        real(dp) :: b, c, vv, disc
        b = dx(1)*dv(1) + dx(2)*dv(2) + dx(3)*dv(3)
        vv = dv(1)**2 + dv(2)**2 + dv(3)**2
        c = dx(1)**2 + dx(2)**2 + dx(3)**2 - rk2
        t = no_event
        if (.not. (vv > 0)) return
        disc = max(b*b - vv*c, 0.0_dp)
        if (b < 0) then
            t = (-b + sqrt(disc))/vv
        else
            t = max(-c/(b + sqrt(disc)), 0.0_dp)
        end if
    end function outward_time

    !> The crossing of a step of height du (huge: a hard core) by the pair at separation dx
    !> (x_i - x_j) with velocities vi, vj and masses mi, mj. On return vi, vj are the new
    !> velocities, crossed tells whether the pair went through (else it reflected) and w is the
    !> collision virial dx . dp_i (dp_i the impulse on i).
    pure subroutine collide(dx, vi, vj, mi, mj, du, crossed, w)
        real(dp), intent(in) :: dx(3), mi, mj, du
        real(dp), intent(inout) :: vi(3), vj(3)
        logical, intent(out) :: crossed
        real(dp), intent(out) :: w
        real(dp) :: e(3), r, vn, vn_new, mu, dp_n, arg
        r = sqrt(dx(1)**2 + dx(2)**2 + dx(3)**2)
        e = dx/r
        vn = (vi(1) - vj(1))*e(1) + (vi(2) - vj(2))*e(2) + (vi(3) - vj(3))*e(3)
        mu = mi*mj/(mi + mj)
        crossed = .false.
        vn_new = -vn
        if (du < huge(1.0_dp)) then
            arg = vn*vn - 2*du/mu
            if (arg > 0) then
                crossed = .true.
                vn_new = sign(sqrt(arg), vn)
            end if
        end if
        dp_n = mu*(vn_new - vn)
        vi = vi + (dp_n/mi)*e
        vj = vj - (dp_n/mj)*e
        w = r*dp_n
    end subroutine collide

end module terrace_stepped_pair
