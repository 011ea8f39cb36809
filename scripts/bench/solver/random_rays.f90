!> Stress search of the energy-stepping event solver (src/integrators/event_solver.f90) on random
!> analytic rays: f(s) = c1 s + c2 s^2 + c3 s^3 + up to three Gaussian bumps (widths 0.05-0.45,
!> heights up to 0.6) + up to one sine, levels 0.02-1.02 either side of f(0), window (0, 2], no trust
!> cap (the engine caps each step by its trust length; this does not). Each ray's first crossing is
!> compared with a brute-force reference (200,000 grid points; a crossing counts when f leaves the
!> levels by more than 10 tol). Prints every ray where the solver returns a later crossing or none,
!> with the largest excursion it stepped over, then the count and the mean ray evaluations per ray,
!> and a checksum of every ray's answer (found, level, the bits of s) and evaluation count: two
!> versions of the solver that decide alike print the same checksum.
!> Usage: random_rays [NRAYS [SEED]]   (defaults 20000, 12345)
module random_rays_mod
    use terrace_kinds, only: dp
    use terrace_event_solver, only: ray_t
    implicit none
    private
    type, extends(ray_t), public :: mix_t
        real(dp) :: c(0:3) = 0
        integer :: ng = 0, ns = 0
        real(dp) :: ga(3) = 0, gm(3) = 0, gw(3) = 1, sa(1) = 0, sw(1) = 0, sp(1) = 0
    contains
        procedure :: eval_ray => mix_eval
    end type mix_t
contains
    subroutine mix_eval(self, s, fdc)
        class(mix_t), intent(inout) :: self
        real(dp), intent(in) :: s
        real(dp), intent(out) :: fdc(3)
        real(dp) :: u, e, x
        integer :: j
        fdc(1) = self%c(0) + s*(self%c(1) + s*(self%c(2) + s*self%c(3)))
        fdc(2) = self%c(1) + s*(2*self%c(2) + 3*s*self%c(3))
        fdc(3) = 2*self%c(2) + 6*s*self%c(3)
        do j = 1, self%ns
            x = self%sw(j)*s + self%sp(j)
            fdc(1) = fdc(1) + self%sa(j)*sin(x)
            fdc(2) = fdc(2) + self%sa(j)*self%sw(j)*cos(x)
            fdc(3) = fdc(3) - self%sa(j)*self%sw(j)**2*sin(x)
        end do
        do j = 1, self%ng
            u = (s - self%gm(j))/self%gw(j)
            e = 0
            if (abs(u) < 38) e = self%ga(j)*exp(-0.5_dp*u*u)
            fdc(1) = fdc(1) + e
            fdc(2) = fdc(2) - e*u/self%gw(j)
            fdc(3) = fdc(3) + e*(u*u - 1)/self%gw(j)**2
        end do
    end subroutine mix_eval
end module random_rays_mod

program random_rays
    use terrace_kinds, only: dp, i8
    use terrace_event_solver, only: event_solver_t, crossing_t
    use random_rays_mod, only: mix_t
    implicit none
    integer, parameter :: n_grid = 200000
    real(dp), parameter :: s_max = 2
    type(mix_t) :: r
    type(event_solver_t) :: solver
    type(crossing_t) :: res
    integer :: i, j, k, nbad, nrays, n_missed, n_later
    integer(i8) :: checksum
    integer(8) :: seed, nev
    real(dp) :: f0(3), lower, upper, fs(3), s_ref, s_end, x, excursion
    character(len=32) :: arg
    nrays = 20000; seed = 12345
    if (command_argument_count() >= 1) then
        call get_command_argument(1, arg); read (arg, *) nrays
    end if
    if (command_argument_count() >= 2) then
        call get_command_argument(2, arg); read (arg, *) seed
    end if
    solver%tol = 1.0e-9_dp
    nbad = 0; nev = 0; n_missed = 0; n_later = 0; checksum = 0
    do i = 1, nrays
        r = mix_t()
        r%c(1) = 2*u01() - 1; r%c(2) = 2*(2*u01() - 1); r%c(3) = 0.5_dp*(2*u01() - 1)
        r%ng = int(3.999_dp*u01())
        do j = 1, r%ng
            r%ga(j) = 0.6_dp*(2*u01() - 1); r%gm(j) = s_max*u01(); r%gw(j) = 0.05_dp + 0.4_dp*u01()
        end do
        r%ns = int(1.999_dp*u01())
        do j = 1, r%ns
            r%sa(j) = 0.3_dp*(2*u01() - 1); r%sw(j) = 1 + 10*u01(); r%sp(j) = 6.28_dp*u01()
        end do
        call r%eval_ray(0.0_dp, f0)
        lower = f0(1) - 0.02_dp - u01(); upper = f0(1) + 0.02_dp + u01()
        r%evals = 0
        call solver%first_crossing(r, lower, upper, s_max, f0, .true., huge(1.0_dp), res)
        nev = nev + r%evals
        checksum = ieor(ishftc(checksum, 7), transfer(res%s, 0_i8))
        checksum = ieor(ishftc(checksum, 7), int(merge(1, 0, res%found) + 4*res%level + 16*r%evals, i8))
        s_ref = -1
        do k = 1, n_grid
            x = k*(s_max/n_grid)
            call r%eval_ray(x, fs)
            if (fs(1) > upper + 10*solver%tol .or. fs(1) < lower - 10*solver%tol) then
                s_ref = x; exit
            end if
        end do
        if (s_ref < 0) cycle
        if (res%found .and. res%s <= s_ref + 1.0e-6_dp) cycle
        nbad = nbad + 1
        s_end = s_max; if (res%found) s_end = res%s
        excursion = 0
        do k = 1, n_grid
            x = k*(s_max/n_grid)
            if (x > s_end) exit
            call r%eval_ray(x, fs)
            excursion = max(excursion, fs(1) - upper, lower - fs(1))
        end do
        if (res%found) then
            n_later = n_later + 1
            write (*, '(a, i7, a, f9.5, a, f9.5, a, es9.2, a, i3)') 'ray', i, ': solver', res%s, ', first crossing', s_ref, &
                ', stepped over an excursion of', excursion, '; evaluations', r%evals
        else
            n_missed = n_missed + 1
            write (*, '(a, i7, a, f9.5, a, es9.2, a, i3)') 'ray', i, ': solver none, first crossing', s_ref, &
                ', excursion', excursion, '; evaluations', r%evals
        end if
    end do
    write (*, '(i0, a, i0, a, i0, a, i0, a, f6.3, a)') nbad, ' of ', nrays, ' rays wrong (', n_later, ' a later crossing, ', &
        n_missed, ' none); ', real(nev, dp)/nrays, ' ray evaluations per ray'
    write (*, '(a, z16.16)') 'checksum of the answers: ', checksum
contains
    real(dp) function u01()
        seed = mod(16807_8*seed, 2147483647_8)
        u01 = real(seed, dp)/2147483647.0_dp
    end function u01
end program random_rays
