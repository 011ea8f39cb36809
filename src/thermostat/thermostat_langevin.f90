!> Langevin dynamics by BAOAB (Leimkuhler & Matthews): velocity Verlet's first half kick and drift
!> become B A O A, the O step the exact Ornstein-Uhlenbeck update between two half drifts,
!>   v <- c1 v + sqrt(1 - c1^2) sqrt(k_B T / m) z,   c1 = exp(-dt / damping),
!> z normal, drawn from the counter-based generator keyed by (seed, atom id, step). The total
!> momentum is not held: dof = d N (less d with zero_momentum).
module terrace_thermostat_langevin
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_counter_rng, only: normals3_many, rng_batch
    use terrace_thermostat, only: thermostat_t, thermostat_traits_t
    implicit none
    private

    integer, parameter :: stream_langevin = 101   !< the generator's stream for this thermostat

    type, extends(thermostat_t), public :: langevin_t
    contains
        procedure, nopass :: style_traits => langevin_traits
        procedure :: kick_drift => langevin_kick_drift
    end type langevin_t

contains

    !> Its B A O A replaces velocity Verlet's first half kick and drift; no energy-stepping form.
    pure type(thermostat_traits_t) function langevin_traits() result(t)
        t = thermostat_traits_t(replaces_kick_drift=.true.)
    end function langevin_traits

    !> BAOAB's B A O A for every owned atom: v += dtfm f, x += dt/2 v, v <- c1 v + c2 sqrt(kT/m) z,
    !> x += dt/2 v, z from (seed, id, step); dtfm(type) = dt/2 ftm2v/m. `t_mid` is the middle of the
    !> step (for the target temperature).
    subroutine langevin_kick_drift(self, atoms, dtfm, dt, step, t_mid)
        class(langevin_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: dtfm(:), dt, t_mid
        integer(i8), intent(in) :: step
        real(dp) :: c1, c2, kt, half, sig(atoms%ntypes), z(rng_batch, 3), de, m2(atoms%ntypes)
        integer :: t, i0, i1, nb
        c1 = exp(-dt/self%damping)
        c2 = sqrt(max(0.0_dp, 1 - c1*c1))
        kt = self%boltz*self%target(t_mid)
        do t = 1, atoms%ntypes
            sig(t) = c2*sqrt(kt/(atoms%mass(t)*self%mvv2e))
            m2(t) = 0.5_dp*self%mvv2e*atoms%mass(t)
        end do
        half = 0.5_dp*dt
        de = 0
        ! batches of atoms: the counter-based draws vectorise across atoms (normals3_many), and so
        ! does the B A O A update of the batch (baoab_batch)
        do i0 = 1, atoms%nlocal, rng_batch
            nb = min(rng_batch, atoms%nlocal - i0 + 1)
            i1 = i0 + nb - 1
            call normals3_many(nb, self%seed, stream_langevin, atoms%id(i0:i1), step, z(1:nb, :))
            if (self%dimension == 2) z(1:nb, 3) = 0
            call baoab_batch(nb, atoms%x(:, i0:i1), atoms%v(:, i0:i1), atoms%f(:, i0:i1), atoms%type(i0:i1), &
                             z(1:nb, 1), z(1:nb, 2), z(1:nb, 3), dtfm, sig, m2, c1, half, de)
        end do
        self%ecouple_local = self%ecouple_local + de
    end subroutine langevin_kick_drift

    !> B A O A on a batch of n atoms (explicit-shape arrays: no aliasing, so the loop vectorises):
    !> v' = v + dtfm f, x += dt/2 v', v'' = c1 v' + sig z, x += dt/2 v''; de gains the kinetic
    !> energy the O step put in (per-atom parts summed in atom order).
    pure subroutine baoab_batch(n, x, v, f, typ, z1, z2, z3, dtfm, sig, m2, c1, half, de)
        integer, intent(in) :: n, typ(n)
        real(dp), intent(inout) :: x(3, n), v(3, n), de
        real(dp), intent(in) :: f(3, n), z1(n), z2(n), z3(n), dtfm(:), sig(:), m2(:), c1, half
        real(dp) :: a1, a2, a3, b1, b2, b3, dk(n)
        integer :: i, t
        do i = 1, n
            t = typ(i)
            a1 = v(1, i) + dtfm(t)*f(1, i)
            a2 = v(2, i) + dtfm(t)*f(2, i)
            a3 = v(3, i) + dtfm(t)*f(3, i)
            b1 = c1*a1 + sig(t)*z1(i)
            b2 = c1*a2 + sig(t)*z2(i)
            b3 = c1*a3 + sig(t)*z3(i)
            x(1, i) = x(1, i) + half*a1 + half*b1
            x(2, i) = x(2, i) + half*a2 + half*b2
            x(3, i) = x(3, i) + half*a3 + half*b3
            v(1, i) = b1; v(2, i) = b2; v(3, i) = b3
            dk(i) = m2(t)*((b1*b1 + b2*b2 + b3*b3) - (a1*a1 + a2*a2 + a3*a3))
        end do
        do i = 1, n
            de = de + dk(i)
        end do
    end subroutine baoab_batch

end module terrace_thermostat_langevin
