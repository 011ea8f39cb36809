!> The Verlet buffer (the list's skin) from an energy-drift tolerance, for a list rebuilt every
!> `every` steps without a check: the estimate of GROMACS's verlet-buffer-tolerance (Pall and Hess
!> 2013; GROMACS manual, "Energy drift and pair-list buffering"), written from its formulas.
!>
!> A pair of atoms of types a and b outside the list at a build (separation beyond rc + skin) and
!> inside the cutoff before the next build exerts no force: that error is what the buffer bounds.
!> Between builds an atom moves ballistically, t = (every - 1) dt at the last step that uses the
!> list, so the pair's separation changes along the line of centres by a Gaussian of variance
!> s2 = kT t^2 (1/m_a + 1/m_b) (per dimension; mvv2e converts m v^2 to energy). With the
!> potential near rc as V(rc - x) - V(rc) ~ -V1 x + V2 x^2/2 - V3 x^3/6 and a uniform density, the
!> energy of the missed pairs per list lifetime is
!>     sum over type pairs  n_ab 4 pi (rc_ab + skin + s)^2 / volume
!>         x ( |V1| M2/2 + |V2| M3/6 + |V3| M4/24 ),   Mk = int_skin^inf (u - skin)^k g_s(u) du,
!> (n_ab: the number of a-b atom pairs; g_s the Gaussian's density) and the drift is that per atom
!> per (every dt). Each derivative counts with its magnitude, so that no attraction and repulsion
!> cancel (an upper estimate; GROMACS keeps only V1 for a plain cut-off, and takes the cluster list's
!> extra pairs off; Terrace keeps all three and does not, so that the same tolerance gives a skin
!> at least as large as GROMACS's atom-pair figure). The skin is the smallest one whose drift is
!> within the tolerance (bisection).
module terrace_verlet_buffer
    use terrace_kinds, only: dp
    implicit none
    private

    public :: buffer_drift, buffer_skin

    real(dp), parameter :: pi = 3.14159265358979323846_dp

contains

    !> Energy drift per atom per unit time for a skin: ntypes types with count(t) atoms of mass(t)
    !> in volume; deriv(:, a, b) = (rc, V'(rc), V''(rc), V'''(rc)) of the a-b pair term (rc > 0);
    !> kt = k_B T (energy), mvv2e (m v^2 to energy), dt and every (steps between builds).
    pure real(dp) function buffer_drift(skin, every, dt, kt, mvv2e, count, mass, volume, deriv) result(drift)
        real(dp), intent(in) :: skin, dt, kt, mvv2e, count(:), mass(:), volume, deriv(:, :, :)
        integer, intent(in) :: every
        integer :: a, b
        real(dp) :: t, s2, npairs, total
        t = (every - 1)*dt
        total = 0
        do b = 1, size(count)
            do a = 1, b
                if (count(a) <= 0 .or. count(b) <= 0) cycle
                s2 = kt*t*t*(1/mass(a) + 1/mass(b))/mvv2e
                if (a == b) then
                    npairs = count(a)*(count(a) - 1)/2
                else
                    npairs = count(a)*count(b)
                end if
                total = total + npairs*4*pi*(deriv(1, a, b) + skin + sqrt(s2))**2/volume*pair_error(skin, s2, deriv(:, a, b))
            end do
        end do
        drift = total/(sum(count)*every*dt)
    end function buffer_drift

    !> The energy error of one pair term per pair density and list lifetime (the bracket above).
    pure real(dp) function pair_error(skin, s2, d) result(e)
        real(dp), intent(in) :: skin, s2, d(4)
        real(dp) :: s, tail, dens, b2
        if (s2 <= 0) then
            e = 0
            return
        end if
        s = sqrt(s2)
        tail = 0.5_dp*erfc(skin/sqrt(2*s2))                    ! P(u > skin)
        dens = exp(-skin*skin/(2*s2))/sqrt(2*pi)               ! s g_s(skin)
        b2 = skin*skin
        e = abs(d(2))/2*((b2 + s2)*tail - skin*s*dens) &
            + abs(d(3))/6*(s*(b2 + 2*s2)*dens - skin*(b2 + 3*s2)*tail) &
            + abs(d(4))/24*((b2*b2 + 6*b2*s2 + 3*s2*s2)*tail - skin*s*(b2 + 5*s2)*dens)
    end function pair_error

    !> The smallest skin whose drift (buffer_drift) is at most tolerance (relative precision 1e-9
    !> of the largest cutoff); drift: its estimated drift. every = 1 needs none (skin 0).
    pure subroutine buffer_skin(tolerance, every, dt, kt, mvv2e, count, mass, volume, deriv, skin, drift)
        real(dp), intent(in) :: tolerance, dt, kt, mvv2e, count(:), mass(:), volume, deriv(:, :, :)
        integer, intent(in) :: every
        real(dp), intent(out) :: skin, drift
        real(dp) :: lo, hi, smax
        integer :: it
        smax = sqrt(max(kt, 0.0_dp)*((every - 1)*dt)**2*2/(minval(mass)*mvv2e))   ! the widest pair's s
        lo = 0
        hi = 12*smax                         ! erfc(12 / sqrt(2)) ~ 2e-33: no drift left
        if (buffer_drift(lo, every, dt, kt, mvv2e, count, mass, volume, deriv) <= tolerance) hi = 0
        do it = 1, 200
            if (hi - lo <= 1e-9_dp*maxval(deriv(1, :, :))) exit
            skin = 0.5_dp*(lo + hi)
            if (buffer_drift(skin, every, dt, kt, mvv2e, count, mass, volume, deriv) <= tolerance) then
                hi = skin
            else
                lo = skin
            end if
        end do
        skin = hi
        drift = buffer_drift(skin, every, dt, kt, mvv2e, count, mass, volume, deriv)
    end subroutine buffer_skin

end module terrace_verlet_buffer
