!> Stochastic cell rescaling (Bernetti and Bussi, J. Chem. Phys. 153, 114107 (2020)), isotropic,
!> first order in eps = ln V:
!>   d eps = -(beta_T / tau_p) (P0 - P_int - k T / V) dt + sqrt(2 k T beta_T / (V tau_p)) dW
!> with P_int = (2 K + W) / (d V), the kinetic energy and virial of the end of the previous step.
!> Applied after each step's drift, before its force pass: the box and the positions are scaled
!> by exp(d eps / d), the velocities by exp(-d eps / d). The noise is one normal number per step,
!> drawn from the counter-based generator keyed by (seed, step): the same on every rank. The
!> volume fluctuations are those of the isothermal-isobaric ensemble (unlike Berendsen's).
!> The effective energy (Bernetti and Bussi's, like CSVR's thermostat energy): each rescaling's work
!> on the system, dK + dU + P0 dV, is accumulated and taken off the conserved quantity (energy =
!> -work), so that econserve = etotal + P0 V - work - ecouple changes only by the integration error.
!> dK = K (mu^-2 - 1) and P0 dV are exact; dU = -int_0^s W(s') ds' (s = ln mu, W the virial) by the
!> trapezoid rule with the virials of the force passes before and after the rescaling.
!>
!> couple = 'aniso': each edge's eps_a = ln L_a on its own (d independent first-order equations
!> with a third of the volume's mobility each, so that sum_a eps_a = ln V moves as above):
!>   d eps_a = -(beta_T / (d tau_p)) (P0 - P_aa - k T / V) dt + sqrt(2 k T beta_T / (d V tau_p)) dW_a
!> with P_aa = (2 K_aa + W_aa) / V. Its stationary distribution is exp(-(U + P0 V)/kT) V^N in
!> (L_x, L_y, L_z) (the Jacobian V of the logarithms gives the k T / V term of each edge). The edge
!> and the positions of axis a are scaled by mu_a = exp(step of eps_a), its velocities by 1/mu_a; the
!> work is sum_a K_aa (mu_a^-2 - 1) + P0 dV - sum_a int W_aa d ln L_a (trapezoid rule as above).
module terrace_barostat_c_rescale
    use terrace_kinds, only: dp, i8
    use terrace_engine, only: engine_t
    use terrace_barostat, only: barostat_t, barostat_params_t, internal_pressure, kinetic_diagonal, pressure_diagonal, &
                                exchange_iso_aniso
    use terrace_counter_rng, only: rng_stream, rng_stream_t
    use terrace_named_values, only: named_values_t
    use terrace_velocities, only: kinetic_energy
    implicit none
    private

    integer, parameter :: stream_c_rescale = 202   !< the generator's stream for this barostat

    type, extends(barostat_t), public :: c_rescale_t
        real(dp) :: p_int = 0                    !< the internal pressure at the end of the last step
        logical :: have_p = .false.
        real(dp) :: work = 0                     !< the rescalings' work on the system so far
        real(dp) :: w_before = 0, log_mu = 0     !< this step's virial before the rescaling, ln mu
        !> aniso: P_aa at the end of the last step, W_aa before this step's rescaling, ln mu_a
        real(dp) :: p_axis(3) = 0, w_axis(3) = 0, log_mu_axis(3) = 0
    contains
        procedure :: before_forces => cr_before_forces
        procedure :: after_step => cr_after_step
        procedure :: energy => cr_energy
        procedure :: exchange_own => cr_exchange
    end type c_rescale_t

contains

    !> The step of eps (aniso: of each edge's eps_a) and its work; the box, the positions and the
    !> velocities scaled by it (module header).
    subroutine cr_before_forces(self, eng, step, moved)
        class(c_rescale_t), intent(inout) :: self
        include 'barostat_hook_args.inc'
        type(rng_stream_t) :: s
        real(dp) :: v, deps, mu, ke, deps_axis(3), ke_axis(3), sd, drift, scale(3)
        integer :: a, d
        if (.not. self%have_p) call measure_pressure(self, eng)    ! the first step: the initial state's
        d = self%p%dimension
        v = eng%box%volume()
        s = rng_stream(self%p%seed, stream_c_rescale, 0_i8, step)
        if (self%p%aniso) then                 ! each edge by its own pressure component and its own noise
            sd = sqrt(2*self%kt*self%beta*self%p%dt/(d*v*self%tau))
            deps_axis = 0
            do a = 1, d
                drift = -(self%beta/(d*self%tau))*(self%p0 - self%p_axis(a) - self%kt/v)*self%p%dt
                deps_axis(a) = drift + sd*s%normal()
            end do
            ke_axis = kinetic_diagonal(eng)
            self%work = self%work + sum(ke_axis(1:d)*(exp(-2*deps_axis(1:d)) - 1)) + self%p0*v*(exp(sum(deps_axis)) - 1)
            self%w_axis = eng%virial_diag
            self%log_mu_axis = deps_axis
            scale = exp(deps_axis)
        else
            deps = -(self%beta/self%tau)*(self%p0 - self%p_int - self%kt/v)*self%p%dt + &
                   sqrt(2*self%kt*self%beta*self%p%dt/(v*self%tau))*s%normal()
            mu = exp(deps/d)
            ke = kinetic_energy(eng%atoms, eng%units)
            self%work = self%work + ke*(1/mu**2 - 1) + self%p0*v*(exp(deps) - 1)
            self%w_before = eng%virial
            self%log_mu = deps/d
            scale = [(merge(mu, 1.0_dp, a <= d), a = 1, 3)]
        end if
        call eng%scale_box(scale, velocities=.true., keep_list=.true., rebuilt=moved)
    end subroutine cr_before_forces

    subroutine cr_after_step(self, eng, step, moved)
        class(c_rescale_t), intent(inout) :: self
        include 'barostat_hook_args.inc'
        moved = .false.
        if (self%p%aniso) then
            self%work = self%work - 0.5_dp*sum(self%log_mu_axis*(self%w_axis + eng%virial_diag))
        else
            self%work = self%work - 0.5_dp*self%log_mu*(self%w_before + eng%virial)
        end if
        call measure_pressure(self, eng)
    end subroutine cr_after_step

    !> The pressure that drives the next rescaling, of the present state: P_int (aniso: the diagonal
    !> P_aa). Collective.
    subroutine measure_pressure(self, eng)
        class(c_rescale_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        if (self%p%aniso) then
            self%p_axis = pressure_diagonal(eng)
        else
            self%p_int = internal_pressure(eng)
        end if
        self%have_p = .true.
    end subroutine measure_pressure

    !> The barostat's term of the conserved quantity: minus the rescalings' work.
    real(dp) function cr_energy(self, eng)
        class(c_rescale_t), intent(in) :: self
        type(engine_t), intent(in) :: eng
        cr_energy = -self%work
    end function cr_energy

    !> The pressure of the end of the last step (aniso: its diagonal) and the work so far.
    subroutine cr_exchange(self, values, saving, ok)
        class(c_rescale_t), intent(inout) :: self
        include 'checkpointed_args.inc'
        call exchange_iso_aniso(values, self%p%aniso, 'baro_p_int', self%p_int, 'baro_p_axis_', self%p_axis, saving, ok)
        call values%exchange('baro_work', self%work, saving, ok)
        if (.not. saving) self%have_p = .true.
    end subroutine cr_exchange

end module terrace_barostat_c_rescale
