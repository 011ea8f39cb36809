!> Nose-Hoover chains (Martyna, Klein & Tuckerman 1992; the Trotter half step of Martyna,
!> Tuckerman, Tobias & Klein 1996 with third-order Suzuki-Yoshida weights): a chain of M
!> thermostats with masses Q1 = Nf k_B T damping^2, Qj = k_B T damping^2 and forces
!>   G1 = (2K - Nf k_B T)/Q1,  Gj = (Q_{j-1} v_{j-1}^2 - k_B T)/Qj;  v <- v exp(-dt v_1 ...).
!> Velocity Verlet: a half step (dt/2) before the first and after the second half kick. The chain
!> holds the energy sum Q_j v_j^2/2 + Nf kT eta_1 + kT sum_{j>1} eta_j (chain_energy), so that
!> etotal + chain energy is conserved. A zero total momentum stays zero: dof = d N - d.
module terrace_thermostat_nose_hoover
    use terrace_kinds, only: dp, i8
    use terrace_atoms, only: atoms_t
    use terrace_named_values, only: named_values_t
    use terrace_thermostat, only: thermostat_t, thermostat_params_t, thermostat_traits_t, total_ke, &
                                  scale_velocities
    implicit none
    private

    type, extends(thermostat_t), public :: nose_hoover_t
        integer :: chain_length = 3
        real(dp), allocatable :: eta(:), v_eta(:)   !< chain positions and velocities
    contains
        procedure :: setup => nhc_setup
        procedure, nopass :: style_traits => nhc_traits
        procedure :: half_step => nhc_half_step
        procedure :: chain_energy => nhc_chain_energy
        procedure :: exchange_own => nhc_exchange
    end type nose_hoover_t

contains

    subroutine nhc_setup(self, p)
        class(nose_hoover_t), intent(inout) :: self
        type(thermostat_params_t), intent(in) :: p
        self%chain_length = max(p%chain_length, 1)
        if (allocated(self%eta)) deallocate (self%eta, self%v_eta)
        allocate (self%eta(self%chain_length), self%v_eta(self%chain_length))
        self%eta = 0; self%v_eta = 0
    end subroutine nhc_setup

    !> The chain scales every velocity alike: a zero total momentum stays zero.
    pure type(thermostat_traits_t) function nhc_traits() result(t)
        t = thermostat_traits_t(holds_momentum=.true., takes_chain=.true.)
    end function nhc_traits

    !> The chain over a time span (a half step of the integrator, through the default pre_kick and
    !> post_kick; it draws nothing: `event` unused): the Trotter factorisation of exp(iL_NHC span),
    !> three Suzuki-Yoshida sub-steps. Collective (one sum).
    subroutine nhc_half_step(self, atoms, span, event, time)
        class(nose_hoover_t), intent(inout) :: self
        type(atoms_t), intent(inout) :: atoms
        real(dp), intent(in) :: span, time
        integer(i8), intent(in) :: event
        real(dp) :: ke, ke0, kt, q(self%chain_length), g(self%chain_length), w(3), d, scale, total_scale, e
        integer :: m, j, k
        m = self%chain_length
        ke = total_ke(self, atoms)
        ke0 = ke
        if (self%dof <= 0) return
        kt = self%boltz*self%target(time)
        q = kt*self%damping**2
        q(1) = self%dof*q(1)
        w(1) = 1/(2 - 2**(1.0_dp/3)); w(3) = w(1); w(2) = 1 - 2*w(1)
        total_scale = 1
        do k = 1, 3
            d = w(k)*span
            call chain_forces()
            self%v_eta(m) = self%v_eta(m) + 0.5_dp*d*g(m)
            do j = m - 1, 1, -1
                e = exp(-0.25_dp*d*self%v_eta(j + 1))
                self%v_eta(j) = (self%v_eta(j)*e + 0.5_dp*d*g(j))*e
            end do
            scale = exp(-d*self%v_eta(1))
            total_scale = total_scale*scale
            ke = ke*scale*scale
            self%eta = self%eta + d*self%v_eta
            g(1) = (2*ke - self%dof*kt)/q(1)
            do j = 1, m - 1
                e = exp(-0.25_dp*d*self%v_eta(j + 1))
                self%v_eta(j) = (self%v_eta(j)*e + 0.5_dp*d*g(j))*e
                g(j + 1) = (q(j)*self%v_eta(j)**2 - kt)/q(j + 1)
            end do
            self%v_eta(m) = self%v_eta(m) + 0.5_dp*d*g(m)
        end do
        call scale_velocities(atoms, total_scale)
        self%ecouple_global = self%ecouple_global + (ke - ke0)
    contains
        subroutine chain_forces()
            integer :: jj
            g(1) = (2*ke - self%dof*kt)/q(1)
            do jj = 2, m
                g(jj) = (q(jj - 1)*self%v_eta(jj - 1)**2 - kt)/q(jj)
            end do
        end subroutine chain_forces
    end subroutine nhc_half_step

    !> Energy held by the chain at time t, sum Q_j v_j^2/2 + Nf kT eta_1 + kT sum_{j>1} eta_j.
    pure real(dp) function nhc_chain_energy(self, time) result(e)
        class(nose_hoover_t), intent(in) :: self
        real(dp), intent(in) :: time
        real(dp) :: kt, q
        integer :: j
        e = 0
        kt = self%boltz*self%target(time)
        do j = 1, self%chain_length
            q = kt*self%damping**2
            if (j == 1) q = self%dof*q
            e = e + 0.5_dp*q*self%v_eta(j)**2
            if (j == 1) then
                e = e + self%dof*kt*self%eta(j)
            else
                e = e + kt*self%eta(j)
            end if
        end do
    end function nhc_chain_energy

    !> The chain's positions and velocities.
    subroutine nhc_exchange(self, values, saving, ok)
        class(nose_hoover_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        if (saving) then
            call values%put_reals('ts_eta_', self%eta(1:self%chain_length))
            call values%put_reals('ts_v_eta_', self%v_eta(1:self%chain_length))
        else
            call values%get_reals('ts_eta_', self%eta(1:self%chain_length), ok)
            call values%get_reals('ts_v_eta_', self%v_eta(1:self%chain_length), ok)
        end if
    end subroutine nhc_exchange

end module terrace_thermostat_nose_hoover
