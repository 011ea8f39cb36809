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
    use terrace_barostat, only: barostat_t, barostat_params_t, internal_pressure, kinetic_diagonal, pressure_diagonal
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
        procedure :: needs_virial => cr_needs_virial
        procedure :: before_forces => cr_before_forces
        procedure :: after_step => cr_after_step
        procedure :: energy => cr_energy
        procedure :: save => cr_save
        procedure :: restore => cr_restore
    end type c_rescale_t

contains

    logical function cr_needs_virial(self, step)
        class(c_rescale_t), intent(in) :: self
        integer(i8), intent(in) :: step
        cr_needs_virial = .true.
    end function cr_needs_virial

    subroutine cr_before_forces(self, eng, step, moved)
        class(c_rescale_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: step
        logical, intent(out) :: moved
        type(rng_stream_t) :: s
        real(dp) :: v, deps, mu, ke
        integer :: d
        if (self%aniso) then
            call rescale_axes(self, eng, step, moved)
            return
        end if
        if (.not. self%have_p) then          ! the first step: the pressure of the initial state
            self%p_int = internal_pressure(eng)
            self%have_p = .true.
        end if
        v = eng%box%volume()
        s = rng_stream(self%seed, stream_c_rescale, 0_i8, step)
        deps = -(self%beta/self%tau)*(self%p0 - self%p_int - self%kt/v)*self%dt + &
               sqrt(2*self%kt*self%beta*self%dt/(v*self%tau))*s%normal()
        mu = exp(deps/self%dimension)
        ke = kinetic_energy(eng%atoms, eng%units)
        self%work = self%work + ke*(1/mu**2 - 1) + self%p0*v*(exp(deps) - 1)
        self%w_before = eng%virial
        self%log_mu = deps/self%dimension
        call eng%scale_box([(merge(mu, 1.0_dp, d <= self%dimension), d = 1, 3)], velocities=.true., &
                           keep_list=.true., rebuilt=moved)
    end subroutine cr_before_forces

    !> couple = 'aniso': each edge rescaled by its own pressure component and its own noise.
    subroutine rescale_axes(self, eng, step, moved)
        class(c_rescale_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: step
        logical, intent(out) :: moved
        type(rng_stream_t) :: s
        real(dp) :: v, deps(3), ke(3), sd, drift
        integer :: a, d
        d = self%dimension
        if (.not. self%have_p) then          ! the first step: the pressure of the initial state
            self%p_axis = pressure_diagonal(eng)
            self%have_p = .true.
        end if
        v = eng%box%volume()
        s = rng_stream(self%seed, stream_c_rescale, 0_i8, step)
        sd = sqrt(2*self%kt*self%beta*self%dt/(d*v*self%tau))
        deps = 0
        do a = 1, d
            drift = -(self%beta/(d*self%tau))*(self%p0 - self%p_axis(a) - self%kt/v)*self%dt
            deps(a) = drift + sd*s%normal()
        end do
        ke = kinetic_diagonal(eng)
        self%work = self%work + sum(ke(1:d)*(exp(-2*deps(1:d)) - 1)) + self%p0*v*(exp(sum(deps)) - 1)
        self%w_axis = eng%virial_diag
        self%log_mu_axis = deps
        call eng%scale_box(exp(deps), velocities=.true., keep_list=.true., rebuilt=moved)
    end subroutine rescale_axes

    subroutine cr_after_step(self, eng, step, moved)
        class(c_rescale_t), intent(inout) :: self
        type(engine_t), intent(inout) :: eng
        integer(i8), intent(in) :: step
        logical, intent(out) :: moved
        moved = .false.
        if (self%aniso) then
            self%work = self%work - 0.5_dp*sum(self%log_mu_axis*(self%w_axis + eng%virial_diag))
            self%p_axis = pressure_diagonal(eng)
            self%have_p = .true.
            return
        end if
        self%work = self%work - 0.5_dp*self%log_mu*(self%w_before + eng%virial)
        self%p_int = internal_pressure(eng)
        self%have_p = .true.
    end subroutine cr_after_step

    !> The barostat's term of the conserved quantity: minus the rescalings' work.
    real(dp) function cr_energy(self, eng)
        class(c_rescale_t), intent(in) :: self
        type(engine_t), intent(in) :: eng
        cr_energy = -self%work
    end function cr_energy

    subroutine cr_save(self, values)
        class(c_rescale_t), intent(inout) :: self
        type(named_values_t), intent(inout) :: values
        if (self%aniso) then
            call values%put_reals('baro_p_axis_', self%p_axis)
        else
            call values%put('baro_p_int', self%p_int)
        end if
        call values%put('baro_work', self%work)
    end subroutine cr_save

    subroutine cr_restore(self, values, ok)
        class(c_rescale_t), intent(inout) :: self
        type(named_values_t), intent(in) :: values
        logical, intent(inout) :: ok
        if (self%aniso) then
            call values%get_reals('baro_p_axis_', self%p_axis, ok)
        else
            self%p_int = values%get_r('baro_p_int', ok)
        end if
        self%work = values%get_r('baro_work', ok)
        self%have_p = .true.
    end subroutine cr_restore

end module terrace_barostat_c_rescale
